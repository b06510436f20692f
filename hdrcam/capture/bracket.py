"""Exposure brackets: fixed (N exposures, E EV apart) or automatic (only the exposures a scene needs).

``--auto`` starts at the requested shortest exposure and goes shorter, ``ev_step`` at a time, while the
region of interest has clipped pixels; then longer until its darker pixels (the profile's SNR percentile)
reach the profile's target SNR under the shot + read noise model, or ``stops`` frames were taken.
Frames are written atomically and never over an existing file; the manifest is rewritten after every
frame and on every way out, saying what happened (see BracketCapture).
"""

from __future__ import annotations

import contextlib
import dataclasses
import datetime as dt
import json
import math
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np
from tqdm import tqdm

from hdrcam.capture.camera import Camera, CapturedFrame, ExposureSettings
from hdrcam.capture.manifest import IN_PROGRESS, MANIFEST_NAME, Bracket, BracketFrame, sha256_of
from hdrcam.capture.notches import (NOTCHES_PER_EV, SHUTTER_NOTCHES, ShutterNotch, bracket_notches, exposure_label,
                                    iso_setting, nearest_shutter, notch_step, shutter_notch_within_range)
from hdrcam.errors import HdrcamError, InputError, Interrupted, OutputExistsError, failure_message
from hdrcam.io.atomic import TEMPORARY_SUFFIX, move_without_clobbering
from hdrcam.io.raw import read_raw
from hdrcam.profiles import CameraSpec

CLIP_MARGIN = 0.01  # of the black-to-white range: samples above white - margin count as clipped
NOTCH_LABEL_TOLERANCE_EV = 0.05  # a --shortest further than this from its notch's label is said to be moved


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

    def __post_init__(self):
        """Refuse (InputError), before anything is shot or written, a plan the camera cannot take: an ISO it does not
        offer, a step that is no whole number of shutter notches, a fixed bracket longer than the shutter's 30 s, a
        shortest exposure beyond the shutter's range, an empty region of interest."""
        if isinstance(self.stops, bool) or not isinstance(self.stops, int) or self.stops < 1:
            raise InputError(f"stops {self.stops!r}: a bracket takes a whole number of exposures, 1 or more")
        if self.iso is not None:
            iso_setting(self.iso)
        shutter_notch_within_range(self.shortest_s)
        if self.roi is not None and (len(self.roi) != 4 or min(self.roi) < 0 or min(self.roi[2:]) < 1):
            raise InputError(f"--roi {','.join(map(str, self.roi))}: expected X,Y,WIDTH,HEIGHT in pixels, X and Y "
                             "0 or more, WIDTH and HEIGHT 1 or more")
        if self.auto:
            notch_step(self.ev_step)
        else:
            bracket_notches(self.shortest_s, self.stops, self.ev_step)

    def check_roi_fits(self, width_px: int, height_px: int) -> None:
        """InputError unless the region of interest lies inside a ``width_px`` x ``height_px`` frame."""
        if self.roi is None:
            return
        x, y, width, height = self.roi
        if x + width > width_px or y + height > height_px:
            raise InputError(f"--roi {x},{y},{width},{height} reaches past the {width_px} x {height_px} px frame "
                             f"(to column {x + width}, row {y + height})")


@dataclasses.dataclass(frozen=True)
class FrameStatistics:
    clipped_px: int  # in the region of interest
    snr_at_percentile: float


def frame_statistics(bayer_dn: np.ndarray, camera: CameraSpec, iso: float, plan: BracketPlan) -> FrameStatistics:
    """Clipped samples and the SNR (shot + read noise) at the plan's percentile, inside the ROI."""
    if plan.roi is not None:
        plan.check_roi_fits(bayer_dn.shape[1], bayer_dn.shape[0])  # the frame the camera sent, not the profile's
        x, y, width, height = plan.roi
        bayer_dn = bayer_dn[y:y + height, x:x + width]
    signal_range = camera.white_level_dn - camera.black_level_dn
    clipped = int(np.count_nonzero(bayer_dn >= camera.white_level_dn - CLIP_MARGIN * signal_range))
    electrons_per_dn = camera.full_well_e / signal_range / (iso / 100.0)
    level_dn = np.percentile(bayer_dn, plan.snr_percentile) - camera.black_level_dn
    electrons = max(float(level_dn) * electrons_per_dn, 0.0)
    snr = electrons / np.sqrt(electrons + camera.read_noise_e ** 2) if electrons > 0 else 0.0
    return FrameStatistics(clipped, float(snr))


def _differing(old, new) -> tuple:
    """Of two settings that differ, the entries that do (both whole unless both are dicts)."""
    if not (isinstance(old, dict) and isinstance(new, dict)):
        return old, new
    keys = [key for key in {**old, **new} if old.get(key) != new.get(key)]
    return {key: old[key] for key in keys if key in old}, {key: new[key] for key in keys if key in new}


class BracketCapture:
    """Shoots one bracket into a folder and records it in bracket.json.

    The manifest is written before the first frame (claiming the folder: a second capture into the same
    folder is refused, never mixed in), after every frame, and on every way out - an error, a camera or
    disk failure, SIGINT or SIGTERM - with ``status`` "incomplete" and the reason, listing every frame on
    disk. ``resume`` continues an incomplete bracket: frames already on disk (checked against their
    sha256) are kept and only the missing exposures are shot.
    """

    def __init__(self, camera: Camera, camera_spec: CameraSpec, folder: Path, *, backend: str,
                 profile: str | None, options: dict | None = None, show_progress: bool = True,
                 true_exposure_s: Callable[[], float] | None = None):
        """``true_exposure_s``: the simulated camera's real shutter time at its current notch (ground truth)."""
        self.camera, self.camera_spec, self.folder = camera, camera_spec, Path(folder)
        self.true_exposure_s = true_exposure_s
        self.backend, self.profile, self.options = backend, profile, options or {}
        self.show_progress = show_progress
        self._taken: dict[int, BracketFrame] = {}  # shutter notch index -> frame already on disk (resume)
        self._shooting: tuple[str, ExposureSettings] | None = None  # the frame being captured now

    def new_bracket(self, plan: BracketPlan, kind: str) -> Bracket:
        """The manifest this capture would write: what ``--resume`` compares with the one on disk."""
        details = self.camera.details() if hasattr(self.camera, "details") else {}  # focus, drive, firmware
        return Bracket(kind=kind, camera={"backend": self.backend, "model": self.camera.model, **details},
                       profile=self.profile, frames=[], status="incomplete", error=IN_PROGRESS,
                       options=dict(self.options, plan=dataclasses.asdict(plan)))

    def shoot(self, plan: BracketPlan, *, dark_notches: list[ShutterNotch] | None = None,
              resume: Bracket | None = None) -> Bracket:
        """Capture lights per ``plan`` (or darks at ``dark_notches``), continuing ``resume`` if given."""
        kind = "dark" if dark_notches is not None else "light"
        bracket = self.new_bracket(plan, kind)
        focus_mode = bracket.camera.get("focus_mode")
        if kind == "light" and focus_mode not in (None, "MF"):
            warnings.warn(f"focus mode is {focus_mode}: the camera focuses again for every frame, so a "
                          "calibration bracket may mix focus positions; focus once and set the lens to MF")
        if resume is not None:
            bracket = self._continued(resume, bracket)
        else:
            first = nearest_shutter(plan.shortest_s)
            if kind == "light" and abs(math.log2(float(first.nominal) / plan.shortest_s)) > NOTCH_LABEL_TOLERANCE_EV:
                bracket.notes.append(f"--shortest {exposure_label(plan.shortest_s)} s is not a shutter notch: taken "
                                     f"as the nearest, {first.label} s")
            bracket.write(self.folder)  # refuses (OutputExistsError) if another capture holds the folder
        try:
            if plan.iso is not None:
                self.camera.set_exposure(iso=plan.iso)
            if dark_notches is not None:
                self._fixed(bracket, dark_notches, dark=True)
            elif plan.auto:
                self._auto(bracket, plan)
            else:
                self._fixed(bracket, bracket_notches(plan.shortest_s, plan.stops, plan.ev_step), dark=False)
        except BaseException as error:
            bracket.status, bracket.error = "incomplete", _stop_reason(error)
            self._list_frame_being_written(bracket)
            with contextlib.suppress(Exception):  # the first failure is the one to report (a full disk, say)
                self._finish(bracket)
            raise
        bracket.status, bracket.error = "complete", None
        self._finish(bracket)
        return bracket

    def check_same_request(self, saved: Bracket, plan: BracketPlan) -> None:
        """InputError unless ``saved`` (this folder's bracket, complete or not) was shot as this capture would
        shoot ``plan``: the same kind, camera, profile and options (the plan, the scene, the seed, ...). A
        capture started with darks (``options["darks"]``) must go on with them; one started without may add them."""
        self._check_same_request(saved, self.new_bracket(plan, saved.kind))

    def _check_same_request(self, saved: Bracket, bracket: Bracket) -> None:
        manifest = self.folder / MANIFEST_NAME
        for what, old, new in (("kind", saved.kind, bracket.kind), ("camera", saved.camera, bracket.camera),
                               ("profile", saved.profile, bracket.profile)):
            if old != new:
                old, new = _differing(old, new)
                raise InputError(f"--resume: {manifest} was shot with {what} {old}, this run has {new}; resume "
                                 "with the same camera, profile and options, or choose another --out")
        if saved.options.get("darks") and not bracket.options.get("darks"):
            raise InputError(f"--resume: {manifest} was started with --darks; resume with --darks too, or "
                             "choose another --out")
        for key in sorted((set(saved.options) | set(bracket.options)) - {"darks"}):
            old, new = saved.options.get(key), bracket.options.get(key)
            if old != new:
                old, new = _differing(old, new)
                raise InputError(f"--resume: {manifest} was shot with {key} {json.dumps(old)}, this run asks "
                                 f"for {json.dumps(new)}; resume with the same options, or choose another --out")

    def _continued(self, saved: Bracket, bracket: Bracket) -> Bracket:
        """``saved`` (an incomplete bracket of this folder) after checking it was shot the same way."""
        manifest = self.folder / MANIFEST_NAME
        if saved.status == "complete":
            raise InputError(f"{manifest}: the capture is complete; nothing to resume")
        self._check_same_request(saved, bracket)
        if bracket.options.get("darks"):  # darks added on resume: the manifest says so from now on
            saved.options["darks"] = True
        for frame, path in zip(saved.frames, saved.paths()):
            if not path.is_file() or sha256_of(path) != frame.sha256:
                raise InputError(f"--resume: {path} is missing or changed since it was captured (sha256); "
                                 "restore it, or start a new capture in another --out")
            self._taken[nearest_shutter(frame.exposure_s).index] = frame
        saved.status, saved.error = "incomplete", IN_PROGRESS
        saved.notes.append(f"resumed {dt.datetime.now().isoformat(timespec='seconds')} with "
                           f"{len(saved.frames)} frames on disk")
        return saved

    def _finish(self, bracket: Bracket) -> None:
        bracket.frames.sort(key=lambda frame: frame.exposure_s)
        bracket.notes.extend(getattr(getattr(self.camera, "session", None), "log", []) or [])
        self._save(bracket)

    def _save(self, bracket: Bracket) -> None:
        bracket.write(self.folder, overwrite=True)  # our own manifest, claimed at the start

    def _list_frame_being_written(self, bracket: Bracket) -> None:
        """A frame the camera wrote just before the capture stopped, before it could be listed, is listed
        with the settings it was shot at (and a note), so that no frame on disk is missing from the manifest -
        if it reads as RAW. One that does not (a garbled download: what stopped the capture) is renamed
        UNREADABLE_PREFIX + its name, kept for a look but never a frame, and that exposure is shot again on
        ``--resume``."""
        if self._shooting is None:
            return
        stem, settings = self._shooting
        listed = {frame.file for frame in bracket.frames}
        for path in sorted(self.folder.glob(f"{stem}.*")):
            if path.name in listed or path.name.startswith(".") or TEMPORARY_SUFFIX in path.name:
                continue
            try:
                read_raw(path)
            except (HdrcamError, OSError) as error:
                kept = _set_aside(path)
                bracket.notes.append(f"{path.name} was written as the capture stopped but does not read as RAW "
                                     f"({failure_message(error) or error}); kept as {kept.name}, not a frame of "
                                     "the bracket (--resume shoots that exposure again)")
                continue
            bracket.frames.append(self._record(path, settings, dt.datetime.fromtimestamp(path.stat().st_mtime)))
            bracket.notes.append(f"{path.name} was written as the capture stopped; listed with the settings "
                                 "it was shot at")

    def _record(self, path: Path, settings: ExposureSettings, timestamp: dt.datetime) -> BracketFrame:
        return BracketFrame(
            file=path.name, sha256=sha256_of(path), exposure_s=settings.exposure_s,
            exposure_label=settings.exposure_label, iso=settings.iso, f_number=settings.f_number,
            timestamp=timestamp.isoformat(), true_exposure_s=self.true_exposure_s() if self.true_exposure_s else None)

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
            shorter = min(notch.index + step, len(SHUTTER_NOTCHES) - 1)  # past the end: the shortest the shutter has
            if shorter == notch.index:
                bracket.notes.append(f"still {statistics[notch.index].clipped_px} clipped px at {notch.label} s, "
                                     "the shortest exposure: add an ND filter")
                break
            notch = SHUTTER_NOTCHES[shorter]
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
        taken = self._taken.get(notch.index)
        if taken is not None:  # resumed: this exposure is already on disk
            if plan is None:
                return None
            bayer_dn = read_raw(self.folder / taken.file).bayer_dn
            return frame_statistics(bayer_dn, self.camera_spec, taken.iso, plan)
        settings = self.camera.set_exposure(exposure_s=notch.true_s)
        stem = self._free_stem("dark" if dark else "frame", bracket)
        self._shooting = (stem, settings)
        frame: CapturedFrame = self.camera.capture(self.folder, stem, dark=dark)
        bracket.frames.append(self._record(frame.path, settings, frame.timestamp))
        self._shooting = None
        self._save(bracket)
        if plan is None:
            return None
        return frame_statistics(frame.raw.bayer_dn, self.camera_spec, settings.iso, plan)

    def _free_stem(self, prefix: str, bracket: Bracket) -> str:
        """The next frame name: numbered in capture order, never one that a file on disk already has."""
        index = len(bracket.frames)
        while any(self.folder.glob(f"{prefix}-{index:02d}.*")):
            index += 1
        return f"{prefix}-{index:02d}"


UNREADABLE_PREFIX = "unreadable-"


def _set_aside(path: Path) -> Path:
    """Rename ``path`` to a free UNREADABLE_PREFIX name beside it (never over a file); the new path."""
    for attempt in range(100):
        target = path.with_name(f"{UNREADABLE_PREFIX}{f'{attempt}-' if attempt else ''}{path.name}")
        try:
            move_without_clobbering(path, target)
        except OutputExistsError:
            continue
        return target
    raise OutputExistsError(f"{path}: no free name to set it aside as unreadable")


def _stop_reason(error: BaseException) -> str:
    """Why a capture stopped, in one line for the manifest."""
    if isinstance(error, Interrupted):
        return f"interrupted ({error})"
    if isinstance(error, KeyboardInterrupt):
        return "interrupted (SIGINT)"
    return failure_message(error) or f"{type(error).__name__}: {error}"
