"""Exposure brackets: fixed (N exposures, E EV apart) or automatic (only the exposures a scene needs).

``--auto`` starts at the requested shortest exposure and goes shorter, ``ev_step`` at a time, while the
region of interest has clipped pixels; then longer until its darker pixels (the profile's SNR percentile)
reach the profile's target SNR under the shot + read noise model, or ``stops`` frames were taken.
Frames are written atomically; the manifest is written even when a capture fails, saying what happened.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path

import numpy as np
from tqdm import tqdm

from hdrcam.capture.camera import Camera, CapturedFrame
from hdrcam.capture.manifest import MANIFEST_NAME, Bracket, BracketFrame, sha256_of
from hdrcam.capture.notches import NOTCHES_PER_EV, SHUTTER_NOTCHES, ShutterNotch, bracket_notches, nearest_shutter
from hdrcam.errors import HdrcamError, OutputExistsError
from hdrcam.profiles import CameraSpec

CLIP_MARGIN = 0.01  # of the black-to-white range: samples above white - margin count as clipped


@dataclasses.dataclass(frozen=True)
class BracketPlan:
    shortest_s: float
    stops: int
    ev_step: float
    iso: float | None = None
    auto: bool = False
    roi: tuple[int, int, int, int] | None = None  # x, y, width, height in pixels
    target_snr: float = 20.0
    snr_percentile: float = 5.0


@dataclasses.dataclass(frozen=True)
class FrameStatistics:
    clipped_px: int  # in the region of interest
    snr_at_percentile: float


def frame_statistics(bayer_dn: np.ndarray, camera: CameraSpec, iso: float, plan: BracketPlan) -> FrameStatistics:
    """Clipped samples and the SNR (shot + read noise) at the plan's percentile, inside the ROI."""
    if plan.roi is not None:
        x, y, width, height = plan.roi
        bayer_dn = bayer_dn[y:y + height, x:x + width]
        if bayer_dn.size == 0:
            raise HdrcamError(f"the region of interest {plan.roi} is outside the {camera.width_px} px frame")
    signal_range = camera.white_level_dn - camera.black_level_dn
    clipped = int(np.count_nonzero(bayer_dn >= camera.white_level_dn - CLIP_MARGIN * signal_range))
    electrons_per_dn = camera.full_well_e / signal_range / (iso / 100.0)
    level_dn = np.percentile(bayer_dn, plan.snr_percentile) - camera.black_level_dn
    electrons = max(float(level_dn) * electrons_per_dn, 0.0)
    snr = electrons / np.sqrt(electrons + camera.read_noise_e ** 2) if electrons > 0 else 0.0
    return FrameStatistics(clipped, float(snr))


class BracketCapture:
    """Shoots one bracket into a folder and records it in bracket.json."""

    def __init__(self, camera: Camera, camera_spec: CameraSpec, folder: Path, *, backend: str,
                 profile: str | None, options: dict | None = None, show_progress: bool = True,
                 true_exposure_s: Callable[[], float] | None = None):
        """``true_exposure_s``: the simulated camera's real shutter time at its current notch (ground truth)."""
        self.camera, self.camera_spec, self.folder = camera, camera_spec, Path(folder)
        self.true_exposure_s = true_exposure_s
        self.backend, self.profile, self.options = backend, profile, options or {}
        self.show_progress = show_progress

    def shoot(self, plan: BracketPlan, *, dark_notches: list[ShutterNotch] | None = None) -> Bracket:
        """Capture lights per ``plan`` (or darks at ``dark_notches``) and write the manifest."""
        kind = "dark" if dark_notches is not None else "light"
        manifest = self.folder / MANIFEST_NAME
        if manifest.exists():
            raise OutputExistsError(f"{manifest} exists: a capture is never overwritten; choose another --out")
        bracket = Bracket(kind=kind, camera={"backend": self.backend, "model": self.camera.model},
                          profile=self.profile, frames=[], options=dict(self.options, plan=dataclasses.asdict(plan)))
        try:
            if plan.iso is not None:
                self.camera.set_exposure(iso=plan.iso)
            if dark_notches is not None:
                self._fixed(bracket, dark_notches, dark=True)
            elif plan.auto:
                self._auto(bracket, plan)
            else:
                self._fixed(bracket, bracket_notches(plan.shortest_s, plan.stops, plan.ev_step), dark=False)
        except (HdrcamError, KeyboardInterrupt) as error:
            bracket.status, bracket.error = "failed", str(error) or type(error).__name__
            self._finish(bracket)
            raise
        self._finish(bracket)
        return bracket

    def _finish(self, bracket: Bracket) -> None:
        bracket.frames.sort(key=lambda frame: frame.exposure_s)
        bracket.notes.extend(getattr(getattr(self.camera, "session", None), "log", []) or [])
        bracket.write(self.folder)

    def _fixed(self, bracket: Bracket, notches: list[ShutterNotch], dark: bool) -> None:
        with tqdm(notches, desc="darks" if dark else "bracket", unit="frame", disable=not self.show_progress) as shots:
            for notch in shots:
                shots.set_postfix_str(notch.label, refresh=False)
                self._shoot_one(bracket, notch, dark)

    def _auto(self, bracket: Bracket, plan: BracketPlan) -> None:
        step = round(plan.ev_step * NOTCHES_PER_EV)
        notch = nearest_shutter(plan.shortest_s)
        statistics = {notch.index: self._shoot_one(bracket, notch, False, plan)}
        while statistics[notch.index].clipped_px and len(statistics) < plan.stops:
            if notch.index + step >= len(SHUTTER_NOTCHES):
                bracket.notes.append(f"still {statistics[notch.index].clipped_px} clipped px at {notch.label} s, "
                                     "the shortest exposure: add an ND filter")
                break
            notch = SHUTTER_NOTCHES[notch.index + step]
            statistics[notch.index] = self._shoot_one(bracket, notch, False, plan)
        longest = SHUTTER_NOTCHES[min(statistics)]
        while statistics[longest.index].snr_at_percentile < plan.target_snr and len(statistics) < plan.stops:
            if longest.index - step < 0:
                break
            longest = SHUTTER_NOTCHES[longest.index - step]
            statistics[longest.index] = self._shoot_one(bracket, longest, False, plan)
        final = statistics[min(statistics)]
        bracket.notes.append(f"auto: {len(statistics)} frames; longest reaches SNR {final.snr_at_percentile:.1f} "
                             f"at the {plan.snr_percentile:g}th percentile (target {plan.target_snr:g}); shortest "
                             f"has {statistics[max(statistics)].clipped_px} clipped px")

    def _shoot_one(self, bracket: Bracket, notch: ShutterNotch, dark: bool,
                   plan: BracketPlan | None = None) -> FrameStatistics | None:
        settings = self.camera.set_exposure(exposure_s=notch.true_s)
        stem = f"{'dark' if dark else 'frame'}-{len(bracket.frames):02d}"
        frame: CapturedFrame = self.camera.capture(self.folder, stem, dark=dark)
        bracket.frames.append(BracketFrame(
            file=frame.path.name, sha256=sha256_of(frame.path), exposure_s=settings.exposure_s,
            exposure_label=settings.exposure_label, iso=settings.iso, f_number=settings.f_number,
            timestamp=frame.timestamp.isoformat(), true_exposure_s=self.true_exposure_s() if self.true_exposure_s else None))
        if plan is None:
            return None
        return frame_statistics(frame.raw.bayer_dn, self.camera_spec, settings.iso, plan)
