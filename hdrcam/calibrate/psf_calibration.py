"""Measured PSF from a point-source bracket: merge on the Bayer data, find the sources, fit the PSF.

Steps (issue 4; REFERENCE.md sec. 5): inverse-variance merge of the bracket in camera RGB (black level
subtracted: a dark frame would add its own read noise, and the annulus below removes any dark offset);
hot pixels found in the darks and samples clipped in every frame get no weight; sources closer to another
than their windows and PSFs allow are left out (a pitch too fine for the size is refused, naming the size it
allows); each source's background is a plane fitted per channel to an annulus just outside its window; the
PSF, the sources' positions and fluxes are fitted jointly on the Bayer samples
(:mod:`hdrcam.calibrate.effective_psf`), so the green centroid lands on the centre pixel and all channels share
that sub-pixel shift; the result is
cropped to a given size, or to the smallest size that holds a given energy fraction, and each channel is
normalised to unit sum. A fit whose residuals stay well above the noise is warned about, and so is a source
whose geometric image, given its diameter, is wider than a pixel (:func:`check_source_size`).
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import warnings
from pathlib import Path

import cv2
import numpy as np

from hdrcam.calibrate.effective_psf import EffectivePsf, fit_effective_psf, fitted_models, phase_coverage
from hdrcam.calibrate.hot_pixels import hot_pixel_map
from hdrcam.calibrate.point_sources import ANNULUS_WIDTH_PX, SourceWindow, channel_map, cut_window, detect_sources
from hdrcam.errors import InputError
from hdrcam.hdr.bracket_input import read_bracket
from hdrcam.hdr.fuse import matching_darks
from hdrcam.hdr.merge import BayerMerge, black_subtracted, dilated, merge_bayer
from hdrcam.hdr.neighbour_mean import neighbour_mean
from hdrcam.io.bad_pixels import BadPixelList
from hdrcam.io.raw import RawFrame
from hdrcam.profiles import CameraSpec, Profile

WINDOW_MARGIN_PX = 2  # room for the sub-pixel placement around the PSF support
SOURCE_SIGMAS = 6.0  # a source's brightest sample above its annulus, in annulus noise sigmas (see peak_significance)
NEGATIVE_ENERGY_LIMIT = 0.01  # largest fraction of a channel's fitted energy below zero (see warn_negative_energy)
CHANNEL_NAMES = ("red", "green", "blue")


@dataclasses.dataclass(frozen=True)
class SourceSize:
    """A point source's physical size and the diameter of its geometric (thin-lens) image on the sensor."""

    diameter_m: float
    distance_m: float  # from the lens
    distance_given: bool  # False: the profile's calibration.point_source_distance_m
    image_px: float  # diameter_m * f / (distance_m - f) / pixel pitch, in pixels
    largest_within_pixel_m: float  # the diameter at distance_m whose image is one pixel wide


def source_size(diameter_m: float | None, distance_m: float | None, profile: Profile) -> SourceSize | None:
    """The geometric image of a source ``diameter_m`` wide (metres) at ``distance_m`` (metres from the lens;
    None: the profile's calibration.point_source_distance_m) through the profile's lens, in the profile's pixels:
    a thin lens images it d * f / (z - f) wide. None when neither is given; InputError, one line, for a distance
    without a diameter, a value that is not a positive finite number, or a distance inside the focal length."""
    if diameter_m is None:
        if distance_m is not None:
            raise InputError(f"a source distance ({distance_m!r} m) without the source's diameter "
                             "(--source-diameter-mm, source_diameter_m): give both")
        return None
    for name, value in (("diameter", diameter_m), ("distance", distance_m)):
        if value is not None and (isinstance(value, bool) or not isinstance(value, numbers.Real)
                                  or not 0 < value < math.inf):
            raise InputError(f"source {name} {value!r} m: a positive, finite number of metres")
    focal_m = profile.lens.focal_length_m
    distance = profile.calibration.point_source_distance_m if distance_m is None else float(distance_m)
    if distance <= focal_m:
        raise InputError(f"source distance {distance:g} m is inside the lens's focal length {focal_m:g} m: nothing "
                         "there is imaged; give the distance from the lens to the source")
    pitch_m = profile.camera.pixel_pitch_m
    image_m_per_m = focal_m / (distance - focal_m)  # the thin lens's magnification at that distance
    return SourceSize(float(diameter_m), distance, distance_m is not None,
                      float(diameter_m) * image_m_per_m / pitch_m, pitch_m / image_m_per_m)


def check_window_fits(size_px: int, height_px: int, width_px: int) -> None:
    """InputError when a source's window - the ``size_px`` PSF, WINDOW_MARGIN_PX and the background annulus
    (ANNULUS_WIDTH_PX) on every side - is larger than the frame: no source could be measured in it."""
    border_px = 2 * (WINDOW_MARGIN_PX + ANNULUS_WIDTH_PX)
    if size_px + border_px <= min(height_px, width_px):
        return
    largest = min(height_px, width_px) - border_px
    largest -= 1 - largest % 2  # odd
    advice = f"give a --size of {largest} px or less" if largest >= 3 else "the frame is too small for any PSF"
    raise InputError(f"PSF size {size_px} px (--size): with its margin and background annulus a source's window is "
                     f"{size_px + border_px} px across, larger than the {width_px} x {height_px} px frame; {advice}")


def check_source_size(source: SourceSize, size_px: int) -> None:
    """Warn when the source's geometric image is wider than a pixel, refuse (InputError) when wider than the PSF
    ``size_px`` (pixels). The data then show the true PSF blurred by the image of the source, a disc
    ``source.image_px`` wide, and the fit matches them to the noise, with a fine reduced chi2 and no other
    warning (measured below). Up to ``size_px`` the bulk of that blurred PSF (the disc blurred by
    the PSF's core) stays on the fitted grid, so the record is the PSF behind a known disc, which a later
    deconvolution could take out: only warned about. A disc wider than the
    fitted PSF puts the bulk of each source's light, not only the PSF's faint wings, outside the fitted grid and
    into the background annulus just beyond the window, where it is subtracted as background: the record would
    hold neither the disc nor the lens's PSF. Measured (24 pinholes 40.6 px apart, simulated DOE, --size 15, the
    PSF blurred by a disc of D px, L1 R/G/B): D 1 px 2.9/1.9/3.5 % as D 0; 1.5 px 35/46/59 %; 2 px 59/76/95 %;
    4 px 98/107/130 %; 8 px 145/152/158 %, none warned of by any other check; at 12 and 16 px the fit moved
    sources out of their windows and refused them as extended objects, naming no size. The error grows smoothly
    to its saturation, with no step to put a lower limit at: any disc over a pixel is far off, which the warning
    says."""
    largest_mm = 1e3 * source.largest_within_pixel_m
    scale = 10.0 ** (math.floor(math.log10(largest_mm)) - 2)  # 3 significant figures, rounded down: within, not over
    within = (f"a source up to {math.floor(largest_mm / scale) * scale:.3g} mm wide at {source.distance_m:g} m "
              "images within one pixel")
    if source.image_px > size_px:
        raise InputError(f"the point source ({1e3 * source.diameter_m:g} mm at {source.distance_m:g} m) images "
                         f"{source.image_px:.1f} px wide, wider than the {size_px} px PSF: the fit would measure the "
                         f"source, not the lens; {within}")
    if source.image_px > 1:
        warnings.warn(f"the point source ({1e3 * source.diameter_m:g} mm at {source.distance_m:g} m) images "
                      f"{source.image_px:.1f} px wide: the measured PSF is the true PSF blurred by a disc about "
                      f"{source.image_px:.1f} px wide, far off in L1 though the fit looks fine; {within}",
                      stacklevel=2)


@dataclasses.dataclass
class PsfCalibration:
    psf: np.ndarray  # 3 x s x s, unit sum per channel, camera RGB
    fit: EffectivePsf  # at the fitted size
    energy_in_crop: np.ndarray  # 3: fraction of the fitted support's energy inside the crop
    windows: list[SourceWindow]
    merge: BayerMerge
    frames: list[RawFrame]
    darks: list[RawFrame] | None
    hot_pixels: int
    rejected_sources: int  # detected but crowded, too close to the frame's edge, clipped everywhere, or faint
    source: SourceSize | None = None  # the point source's size and geometric image, where its diameter was given

    @property
    def background(self) -> np.ndarray:
        """Median background per channel over the sources' annuli (merge units)."""
        return np.median([w.background for w in self.windows], axis=0)

    @property
    def peak_snr(self) -> np.ndarray:
        """Per channel: median over sources of the fitted peak signal over the annulus noise."""
        peaks = self.fit.flux * self.fit.psf.max(axis=(1, 2))[None, :]
        noise = np.array([w.noise for w in self.windows])
        return np.median(peaks / np.maximum(noise, 1e-30), axis=0)


def centred_energy(psf: np.ndarray, size: int) -> np.ndarray:
    """Per channel energy inside the centred size x size square."""
    start = psf.shape[-1] // 2 - size // 2
    return psf[:, start:start + size, start:start + size].sum(axis=(1, 2))


def crop_size_for_energy(psf: np.ndarray, fraction: float) -> int:
    """The smallest odd size whose centred square holds ``fraction`` of every channel's energy."""
    for size in range(1, psf.shape[-1] + 1, 2):
        if centred_energy(psf, size).min() >= fraction * psf.sum(axis=(1, 2)).min():
            return size
    return psf.shape[-1]


def peak_significance(window: SourceWindow) -> float:
    """The window's brightest trusted sample above its background, in sigmas of its channel's annulus noise.

    A point source through the DOE keeps half or more of its energy in one pixel, so its peak stands far above
    the noise; noise peaks of a flat or empty frame do not reach SOURCE_SIGMAS (6 sigma: a false alarm rate
    of ~1e-9 per sample under Gaussian noise, as for hot pixels).
    """
    trusted = window.weight > 0
    noise = np.maximum(window.noise[window.channel[trusted]], 1e-30)
    return float((window.rate[trusted] / noise).max(initial=0.0))


def check_enough_samples(windows: list[SourceWindow], size_px: int, left_out: list[str] | None = None) -> None:
    """Refuse sources too few to determine the PSF: each channel has size_px^2 unknowns, and a source gives
    one equation per trusted sample of that channel's CFA sites in its window (a quarter of them for red
    and blue). Fewer equations than unknowns leave the PSF to the smoothness prior - one source gives the
    red and blue PSFs off by ~100 % L1 - so at least as many samples as unknowns are asked for per channel
    (a necessary condition; warn_negative_energy flags sources that are many but too faint). ``left_out``: why
    the other sources found were not used ("N clipped in every frame ..."), named in the refusal: pinholes too
    bright for the shortest exposure left one of 48 usable, and the refusal asked for more pinholes than the 48
    the target had."""
    for channel, name in enumerate(CHANNEL_NAMES):
        samples = sum(int(((w.channel == channel) & (w.weight > 0)).sum()) for w in windows)
        if samples < size_px * size_px:
            others = f"; left out: {', '.join(left_out)}" if left_out else ""
            raise InputError(f"too few point sources for a {size_px} px PSF: {len(windows)} give {samples} "
                             f"{name} samples for its {size_px * size_px} unknowns{others}; use more sources at "
                             "different positions (a pinhole array: capture bracket --scene pinholes)")


PHASE_COVERAGE_LIMIT = 0.8  # least phase_coverage of the fitted positions, every channel (see check_phase_coverage)
GUESS_COVERAGE_LIMIT = 0.6  # the same of the first guesses, before the fit: sources that share one phase


def check_phase_coverage(windows: list[SourceWindow], positions_px: np.ndarray, limit: float) -> None:
    """Refuse sources whose sub-pixel and CFA phases leave part of a channel's PSF grid unmeasured
    (:func:`~hdrcam.calibrate.effective_psf.phase_coverage` under ``limit``). A rigid pinhole grid whose pitch is
    near a whole number of pixels puts every pinhole at nearly the same phase; the fit then explains the data to
    the noise (reduced chi2 0.93) with a wrong PSF, no check objecting: 15 pinholes 80.1 px apart, blue 98 % off
    in L1, coverage 0.75 (the 72.6 and 81.1 px grids beside it: 1.0).

    Measured on 106 grids of 24 pinholes through the simulated DOE (256 x 192 px frames, --size 15; 96 rigid at
    pitches 40.00-41.50 px, 3-6 start offsets each, 10 at random sub-pixel offsets; 3 more the other checks
    refused), coverage of the fitted positions against the worst channel's L1: the 26 at 0.25-0.751 gave 11-172 %,
    but one 5.9 % (at 0.751); the 80 at 0.867-1 gave a median of 4.3 %, 8.4 % at most but five (9-18 %) and one
    misfit that check_fit warns of. At 63 px (15 pinholes, 480 x 320 px) 80.1 px pitches gave 0.73-0.75 (L1
    36-98 %). Hence PHASE_COVERAGE_LIMIT 0.8. Coverage of the first guesses (window centroids) is noisier: 0.81
    at least on every grid the fit got right, 0.25-0.5 on the 12 whose pinholes share one phase (pitch 40.00-40.05
    px; 80.0 and 80.03 px at 63 px, whose fits end out of their windows or at chi2 832): GUESS_COVERAGE_LIMIT
    refuses those before the fit."""
    coverage = phase_coverage(windows, positions_px)
    worst = int(np.argmin(coverage))
    if coverage[worst] < limit:
        raise InputError(f"the point sources sample only {100 * coverage[worst]:.0f} % of the "
                         f"{CHANNEL_NAMES[worst]} PSF grid's sub-pixel phases ({100 * limit:.0f} % "
                         "needed): they sit at nearly the same phase, as on a pinhole grid whose pitch is near a "
                         "whole number of pixels; turn the target a degree or two, use a pitch away from a whole "
                         "number of pixels, or add pinholes")


def warn_negative_energy(fit: EffectivePsf) -> None:
    """Warn when the fitted PSF is dominated by fit error: a true PSF is >= 0, so the energy the fit puts
    below zero (clipped afterwards) is error, and the L1 error of the unclipped fit is at least that fraction of
    the channel's energy (in practice 3-4 times it). NEGATIVE_ENERGY_LIMIT (1 %) is half the 2 % L1 the
    calibration is accepted at. Measured on 600 x 400 px pinhole arrays (28 sources, red, the worst channel):
    power 50 (default) 0.007 % negative, L1 3.2 %; power 10 0.2 %, L1 5.2 %; power 2 2.4 %, L1 7.9 %
    (warned); power 0.5 13 %, L1 28 % (warned). A --size smaller than the PSF's support also shows here (its
    wings fall in the background annulus): 21 % (blue) for a DOE PSF fitted at 31 px. A warning, not a
    refusal, so such a record can still be inspected."""
    worst = int(np.argmax(fit.negative_energy))
    if fit.negative_energy[worst] > NEGATIVE_ENERGY_LIMIT:
        warnings.warn(f"the PSF is poorly constrained: {100 * fit.negative_energy[worst]:.1f} % of the fitted "
                      f"{CHANNEL_NAMES[worst]} energy is negative (over {100 * NEGATIVE_ENERGY_LIMIT:g} %), so its "
                      "L1 error is at least that; use brighter or more point sources, or a larger --size",
                      stacklevel=2)


def crowded(sources: list[tuple[int, int]], peaks: list[tuple[int, int]], support_px: int, reach_px: int
            ) -> dict[tuple[int, int], int]:
    """The sources with a bright peak (of ``peaks``) beyond their own PSF's support (``support_px``: nearer, it is
    the source's own, as a dual-peak DOE's 6 % peak 8 px out) but closer than ``reach_px`` (distances: the larger
    of the row and column offsets), each with that distance: a window of half-width h around a source and a
    neighbour's PSF of radius r overlap when the two are less than h + r + 1 apart, the neighbour's light then
    fitted as the source's own (a 72 px pinhole pitch with an 81 px PSF: L1 26-45 %)."""
    if not sources or not peaks:
        return {}
    distance = np.abs(np.array(sources)[:, None, :] - np.array(peaks)[None, :, :]).max(axis=-1)
    distance = np.where(distance > support_px, distance, np.iinfo(distance.dtype).max)
    nearest = distance.min(axis=1)
    return {sources[index]: int(nearest[index]) for index in np.flatnonzero(nearest < reach_px)}


def _crowding_advice(crowded_sources: dict[tuple[int, int], int], size_px: int) -> str:
    """Why crowded sources were left out, with the spacing the PSF size needs and the largest odd --size their
    spacing allows: an odd size s is free of crowding at a spacing d when d >= (s // 2 + WINDOW_MARGIN_PX) + s // 2
    + 1 = s + WINDOW_MARGIN_PX. The sparser target comes first: a --size smaller than the PSF cuts its light (the
    A7 profile's 255 px rank-1 PSF at 141 px: its streaks' lobes were found as sources of their own)."""
    spacing = int(np.median(list(crowded_sources.values())))
    largest = spacing - WINDOW_MARGIN_PX
    largest -= 1 - largest % 2  # odd
    target = f"a target at least {size_px + WINDOW_MARGIN_PX} px apart"
    size_advice = f"{target}, or --size {largest} if the PSF's light fits in it" if largest >= 3 else target
    return (f"closer to another than a {size_px} px PSF and its window allow (pinholes {spacing} px apart: "
            f"{size_advice})")


MISFIT_CHI2 = 2.0  # reduced chi2 of a good fit: 0.9-1.2 (PRNU of 1 %, vignetting, dust, colour across the plate)
FAILED_FIT_CHI2 = 100.0  # beyond this the fit is no PSF at all: refused rather than written


def check_fit(fit: EffectivePsf, crowded_count: int) -> None:
    """Warn when the model leaves residuals well above the noise (reduced chi2 over MISFIT_CHI2): measured with
    frames that moved 0.1 px between exposures (chi2 6.7, L1 8-16 %) and pinholes whose neighbours' light falls
    in their windows (chi2 13-38, L1 10-45 %), each without any other warning before. InputError beyond
    FAILED_FIT_CHI2 (a dual-peak DOE's pinholes at --size 25: chi2 1683, 370 % of blue's energy negative)."""
    crowding = f"; {crowded_count} crowded pinholes were left out" if crowded_count else ""
    causes = ("frames that moved between exposures, pinholes whose neighbours' light reaches their window, a "
              "resolved (too large) pinhole or a changing background")
    if fit.reduced_chi2 > FAILED_FIT_CHI2:
        raise InputError(f"the PSF fit failed: it leaves {fit.reduced_chi2:.0f} times the noise in the residuals "
                         f"(reduced chi2{crowding}); {causes}? Check the bench and the bracket, or try another --size")
    if fit.reduced_chi2 > MISFIT_CHI2:
        warnings.warn(f"the PSF model leaves {fit.reduced_chi2:.1f} times the noise in the residuals (reduced chi2 "
                      f"over {MISFIT_CHI2:g}{crowding}): {causes} put the PSF several % off - check the bench and "
                      "the bracket", stacklevel=2)


FRAME_SHIFT_LIMIT_PX = 0.02  # of the common shift of the sources between two frames (see warn_frame_motion)
FRAME_TURN_LIMIT_PX = 0.2  # rms over the sources of the displacement a turn between two frames gives them
MOTION_SIGMAS = 5.0  # a motion must also stand this many of its own standard errors out of the noise
FRAME_SOURCE_SNR = 20.0  # least flux significance of a source in one frame for its position there to count


def frame_positions(windows: list[SourceWindow], fit: EffectivePsf, frames: list[RawFrame], merge: BayerMerge
                    ) -> np.ndarray:
    """n sources x f frames x 3: each source's offset (dy, dx, px) from its fitted position in each frame alone,
    and the offset's standard error (NaN where the frame has too little unclipped signal of it): a weighted linear
    fit of the frame's black-subtracted samples that the merge used to the fitted model, its position derivatives
    and a background plane per channel (a level alone let a lit room's slope, 0.4 full wells across 640 px, read
    as a 0.13 px shift). The fitted PSF has partly absorbed a motion, so the offsets between frames read
    a quarter to a half of the true motion (0.1 and 0.2 px shifts: 0.03-0.05 px)."""
    positions = np.full((len(windows), len(frames), 3), np.nan)
    models = fitted_models(windows, fit)
    read_variance, gain = merge.noise.read_noise_dn ** 2, merge.noise.gain_dn_per_e
    for index, (window, (model, d_y, d_x)) in enumerate(zip(windows, models)):
        rows = slice(window.top, window.top + model.shape[0])
        columns = slice(window.left, window.left + model.shape[1])
        y, x = np.mgrid[:model.shape[0], :model.shape[1]] - model.shape[0] // 2
        planes = [(window.channel == c) * term for c in range(3) for term in (1, y, x)]
        terms = np.stack([model, d_y, d_x] + planes, axis=-1).astype(np.float64)
        for k, frame in enumerate(frames):
            used = ((merge.usable_frames[rows, columns] >> k) & 1 == 1) & (window.weight > 0)
            if used.sum() < 2 * terms.shape[-1]:
                continue
            data = black_subtracted(frame, (rows, columns))[used].astype(np.float64)  # the window alone
            root_weight = 1.0 / np.sqrt(read_variance + gain * np.maximum(data, 0.0))
            design = terms[used] * root_weight[:, None]
            design = design[:, np.abs(design).max(axis=0) > 0]  # a channel with no sample in this frame
            solution, *_ = np.linalg.lstsq(design, data * root_weight, rcond=None)
            covariance = np.linalg.pinv(design.T @ design)
            scale = solution[0]
            if not scale > FRAME_SOURCE_SNR * np.sqrt(covariance[0, 0]):
                continue
            positions[index, k] = (solution[1] / scale, solution[2] / scale,
                                   np.sqrt(covariance[1, 1] + covariance[2, 2]) / scale)
    return positions


def frame_motion(positions: np.ndarray, fit: EffectivePsf, shape: tuple[int, int], first: int, second: int
                 ) -> tuple[float, float, float, float] | None:
    """The motion of the sources from frame ``first`` to ``second``: (common shift px, its significance in
    standard errors, rms displacement px of the turn about the frame's centre, its significance), fitted by least
    squares to the sources measured in both (:func:`frame_positions`); None with fewer than 3 such sources."""
    both = np.isfinite(positions[:, first, 0]) & np.isfinite(positions[:, second, 0])
    if both.sum() < 3:
        return None
    moved = (positions[both, second, :2] - positions[both, first, :2]).ravel()
    y, x = (fit.positions_px[both] - np.array(shape) / 2).T
    design = np.zeros((moved.size, 3))
    design[0::2, 0], design[1::2, 1] = 1.0, 1.0
    design[0::2, 2], design[1::2, 2] = x, -y  # a small turn by theta moves (y, x) by theta (x, -y)
    solution, *_ = np.linalg.lstsq(design, moved, rcond=None)
    residual = moved - design @ solution
    error = np.hypot(positions[both, first, 2], positions[both, second, 2]) / np.sqrt(2)
    variance = max(float(residual @ residual) / max(moved.size - 3, 1), float(np.mean(error ** 2)))
    covariance = np.linalg.pinv(design.T @ design) * variance
    shift = solution[:2]
    shift_sigmas = float(np.sqrt(shift @ np.linalg.pinv(covariance[:2, :2]) @ shift))
    radius = float(np.sqrt(np.mean(x ** 2 + y ** 2)))
    turn_sigmas = abs(float(solution[2])) / max(float(np.sqrt(covariance[2, 2])), 1e-30)
    return float(np.hypot(*shift)), shift_sigmas, abs(float(solution[2])) * radius, turn_sigmas


def warn_frame_motion(windows: list[SourceWindow], fit: EffectivePsf, frames: list[RawFrame], merge: BayerMerge
                      ) -> None:
    """Warn when the sources moved between two frames of the bracket (the camera or the target moved between
    exposures, or the frames come from two captures). The merge takes each pinhole's core from a short frame and
    its wings from the long ones, so a motion between them puts the wings off the core, and the fit writes that
    into the PSF at a reduced chi2 that looks fine: on 640 x 480 px pinhole brackets (63 px PSF, 35 sources,
    L1 R/G/B 4.1 / 1.7 / 2.6 % unmoved), shifts of 0.05 and 0.1 px per frame gave 7.1 / 3.8 / 5.4 % (chi2 0.99)
    and 11.4 / 6.2 / 10.2 % (chi2 1.13), a turn of 0.2 degrees 12.6 / 9.4 / 13.9 % (chi2 1.85), none warned of.
    :func:`frame_positions` read those as common shifts of 0.025-0.05 px, and rms turns of 0.4 px (0.2 degrees),
    against at most 0.003 px and 0.01 px unmoved; hence FRAME_SHIFT_LIMIT_PX and FRAME_TURN_LIMIT_PX. A shift of
    0.03 px per frame (L1 5.2 / 2.5 / 3.4 %) reads 0.016 px and passes; a turn of 0.05 degrees (rms 0.13 px, L1 4.7
    / 1.9 / 2.9 %) is warned of for the common shift of 0.022 px it leaves - a real motion, if a harmless one."""
    positions = frame_positions(windows, fit, frames, merge)
    worst = None
    for first in range(len(frames)):
        for second in range(first + 1, len(frames)):
            motion = frame_motion(positions, fit, merge.rate.shape, first, second)
            if motion is None:
                continue
            shift, shift_sigmas, turn, turn_sigmas = motion
            excess = max(shift / FRAME_SHIFT_LIMIT_PX if shift_sigmas > MOTION_SIGMAS else 0.0,
                         turn / FRAME_TURN_LIMIT_PX if turn_sigmas > MOTION_SIGMAS else 0.0)
            if excess > 1 and (worst is None or excess > worst[0]):
                worst = (excess, first, second, shift, turn)
    if worst is not None:
        _, first, second, shift, turn = worst
        names = [frames[k].metadata.path.name for k in (first, second)]
        turned = f", a turn moving them {turn:.2f} px rms" if turn >= FRAME_TURN_LIMIT_PX / 2 else ""
        warnings.warn(f"the point sources moved between {names[0]} and {names[1]} (a common shift of at least "
                      f"{shift:.3f} px{turned}): the camera or target moved between "
                      "exposures, or the frames come from different captures, which puts the PSF several % off - "
                      "fix the camera and the target and shoot the bracket again", stacklevel=2)


def calibrate_psf(sources: list[Path], camera: CameraSpec, *, darks: Path | None, size_px: int,
                  energy_fraction: float | None = None, source: SourceSize | None = None,
                  bad_pixels: BadPixelList | None = None) -> PsfCalibration:
    """``source`` (:func:`source_size`): the point source's size, checked before any work
    (:func:`check_source_size`) and kept in the result; None: not checked. ``bad_pixels``: the sensor's listed
    defects (a dcraw list), left out of the fit as the hot pixels found in ``darks`` are."""
    if isinstance(size_px, bool) or not isinstance(size_px, int) or size_px < 3 or size_px % 2 == 0:
        raise InputError(f"PSF size {size_px!r}: an odd number of pixels, 3 or more (the axis is the centre pixel)")
    if energy_fraction is not None and not 0 < energy_fraction <= 1:
        raise InputError(f"energy fraction {energy_fraction!r}: a fraction of the light, above 0 and at most 1")
    if source is not None:
        check_source_size(source, size_px)
    frames = read_bracket(sources)
    check_window_fits(size_px, *frames[0].bayer_dn.shape)  # before the merge, and the detection's size^2 kernel
    dark_frames = matching_darks(frames, darks)
    merge = merge_bayer(frames, camera, scene_fills_frame=False)  # a bracket without sources is refused below
    # darks find hot pixels; the annulus takes any dark offset out
    meta = frames[0].metadata
    height, width = merge.rate.shape
    noise = merge.noise
    hot = hot_pixel_map(dark_frames, noise.read_noise_dn, noise.gain_dn_per_e) if dark_frames else \
        np.zeros((height, width), bool)
    if bad_pixels is not None:
        hot |= bad_pixels.mask((height, width), meta.timestamp)
    untrusted = dilated(merge.clipped_everywhere) | hot
    weight = np.where(untrusted, 0.0, 1.0 / merge.variance_at(neighbour_mean(merge.rate)))
    channels = channel_map(meta.cfa_pattern, height, width)
    half = size_px // 2 + WINDOW_MARGIN_PX
    found, edge, clipped, faint = {}, 0, 0, 0
    for row, column in detect_sources(merge.rate, ~untrusted, size_px):
        window = cut_window(merge.rate, weight, channels, row, column, half)
        if window is None:
            edge += 1
        elif merge.clipped_everywhere[row - half:row + half + 1, column - half:column + half + 1].any():
            clipped += 1
        elif peak_significance(window) < SOURCE_SIGMAS:
            faint += 1
        else:
            found[(row, column)] = window
    peaks = detect_sources(merge.rate, ~untrusted, 3)  # every bright peak: a neighbour the detection above hid
    crowded_sources = crowded(list(found), peaks, size_px // 2, half + size_px // 2 + 1)
    windows = [window for position, window in found.items() if position not in crowded_sources]
    rejected = edge + clipped + faint + len(crowded_sources)
    reasons = [f"{count} {reason}" for count, reason in (
        (len(crowded_sources), _crowding_advice(crowded_sources, size_px) if crowded_sources else ""),
        (clipped, "clipped in every frame (add a shorter exposure)"), (edge, "too close to the frame's edge"),
        (faint, f"less than {SOURCE_SIGMAS:g} sigma above the background (a flat or empty scene?)")) if count]
    spots = 0 if clipped else cv2.connectedComponents(merge.clipped_everywhere.astype(np.uint8))[0] - 1
    if spots:  # sources clipped whole are masked out before detection: say so
        reasons.insert(0, f"{spots} spots clipped in every frame, not measurable (add a shorter exposure)")
    if not windows:
        if spots and rejected:  # "N found - ..." lists them (with none found: "no point source found ...")
            rejected += spots
        raise InputError(f"no usable point source: {rejected} found - " + ", ".join(reasons) if rejected else
                         "no point source found in the bracket" + (f": {reasons[0]}" if reasons else ""))
    check_enough_samples(windows, size_px, reasons)
    check_phase_coverage(windows, np.array([[w.y_px, w.x_px] for w in windows]), GUESS_COVERAGE_LIMIT)
    fit = fit_effective_psf(windows, size_px)
    check_fit(fit, len(crowded_sources))  # a failed fit is refused in one line, before any other warning
    check_phase_coverage(windows, fit.positions_px, PHASE_COVERAGE_LIMIT)
    warn_frame_motion(windows, fit, frames, merge)  # before warn_negative_energy: the cause before the symptom
    warn_negative_energy(fit)
    crop = size_px if energy_fraction is None else crop_size_for_energy(fit.psf, energy_fraction)
    start = size_px // 2 - crop // 2
    psf = fit.psf[:, start:start + crop, start:start + crop]
    energy = psf.sum(axis=(1, 2))
    return PsfCalibration(psf / energy[:, None, None], fit, energy, windows, merge, frames, dark_frames,
                          int(hot.sum()), rejected, source)
