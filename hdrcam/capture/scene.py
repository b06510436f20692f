"""Scenes for the simulated camera: linear radiance images and point sources.

Radiance is relative: 1.0 just fills the sensor (full well, base ISO) at the simulated camera's reference
exposure. A ``PointSource`` is an unresolved emitter (the PSF calibration target: a source < 0.59 mm wide at
5 m images within one A7 pixel, REFERENCE.md sec. 5); its ``power`` is the total relative radiance it puts
on the sensor, spread by the PSF, at a sub-pixel position.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import cv2
import numpy as np

from hdrcam.data.hdr_folder import warn_negative_radiance
from hdrcam.data.night_scene import night_scene
from hdrcam.errors import InputError
from hdrcam.io.exr import read_exr
from hdrcam.limits import check_image_size

# scene, irradiance, electrons, noise and the Bayer frame (measured: 36 bytes a pixel for 2048 x 1536, x 2)
SIMULATED_CAMERA_BYTES_PER_PIXEL = 72

SCENE_KINDS = ("point", "pinholes", "night", "flat")
DEFAULT_PINHOLE_SPACING_PX = 72  # > the simulated profile's 63 px PSF plus an annulus for the background; denser
# than that costs the fit its background annulus, sparser costs sources: at 96 px (80 sources) blue, whose PSF keeps
# 75 % of its energy in one pixel sampled at a quarter of the sites, was off by 2.2-3.5 % L1 on two of three seeds
PINHOLE_MARGIN_PX = 9  # spacing beyond the PSF for the background annulus (72 px for the simulated profile's 63)
PINHOLE_PITCH_FRACTION_PX = 0.6  # the default pitch's part beyond a whole pixel: a real target's pitch on the
# sensor is no whole number of pixels, so its pinholes land at every CFA and sub-pixel phase (0, 0.6, 1.2, 1.8,
# 0.4, ... px into the 2 px CFA period). A whole pitch puts all at one phase: at the A7 profile's 264 px, each
# pinhole's own sub-pixel offset within one pixel left blue's PSF core unsampled, 12.9 % off in L1 (264.6: 2.5 %)
CFA_PERIOD_PX = 2  # a 2 x 2 colour filter array repeats every 2 pixels
MIN_PINHOLE_SPACING_PX = 2 * CFA_PERIOD_PX  # closer pinholes are no target (and a sub-pixel pitch: millions)
DEFAULT_POINT_POWER = 50.0  # PSF peak ~ half the full well at 1/4000 s with the default reference exposure


@dataclasses.dataclass(frozen=True)
class PointSource:
    x_px: float  # column of the image of the source, pixel centres at integers
    y_px: float
    power: float  # total relative radiance (sum over the PSF), per channel
    colour: tuple[float, float, float] = (1.0, 1.0, 1.0)


@dataclasses.dataclass(frozen=True)
class Scene:
    """What the camera looks at: an H x W x 3 radiance image (or None = black) plus point sources."""

    height_px: int
    width_px: int
    radiance: np.ndarray | None = None
    points: tuple[PointSource, ...] = ()
    description: str = ""

    def dark(self) -> "Scene":
        """The same framing with the lens covered."""
        return Scene(self.height_px, self.width_px, None, (), f"dark ({self.description})")


def load_scene(spec: str, height_px: int, width_px: int, seed: int = 0, *,
               pinhole_spacing_px: float = DEFAULT_PINHOLE_SPACING_PX + PINHOLE_PITCH_FRACTION_PX) -> Scene:
    """``point[:POWER]`` | ``pinholes[:POWER[:SPACING]]`` | ``night`` | ``flat[:LEVEL]`` | an EXR file (scaled to
    cover the sensor, centre crop).

    ``pinholes`` is a pinhole-array calibration target: a rigid grid of equal point sources SPACING pixels apart
    (fractional allowed; default ``pinhole_spacing_px``: pinhole_spacing_for(PSF size) gives the camera's, a
    fractional pitch whose pinholes land at every sub-pixel and CFA phase, so together they sample the PSF
    densely; a whole-pixel SPACING puts them all at one phase, as a real target square to the sensor at such a
    pitch would, which calibration refuses).
    """
    check_image_size("the simulated frame", height_px, width_px, SIMULATED_CAMERA_BYTES_PER_PIXEL,
                     "use a smaller --size")
    kind, _, argument = spec.partition(":")
    if kind == "point":
        power = _number(spec, argument, DEFAULT_POINT_POWER, "POWER")
        rng = np.random.default_rng(seed)
        offset = rng.uniform(-0.5, 0.5, 2)
        source = PointSource(width_px // 2 + float(offset[0]), height_px // 2 + float(offset[1]), power)
        return Scene(height_px, width_px, None, (source,), f"point source, power {power:g}, "
                                                           f"at ({source.x_px:.3f}, {source.y_px:.3f}) px")
    if kind == "pinholes":
        power_text, _, spacing_text = argument.partition(":")
        power = _number(spec, power_text, DEFAULT_POINT_POWER, "POWER")
        spacing = _number(spec, spacing_text, pinhole_spacing_px, "SPACING")
        if spacing < MIN_PINHOLE_SPACING_PX:
            raise InputError(f"scene {spec!r}: pinholes {spacing:g} px apart; give a SPACING of at least "
                             f"{MIN_PINHOLE_SPACING_PX} px (the default follows the PSF: {pinhole_spacing_px:g} px)")
        points = pinhole_grid(height_px, width_px, spacing, power, seed)
        if not points:
            raise InputError(f"scene {spec!r}: no pinhole fits a {width_px} x {height_px} frame {spacing:g} px apart")
        return Scene(height_px, width_px, None, points, f"pinhole array, {len(points)} sources {spacing:g} px apart, "
                                                         f"power {power:g} each")
    if kind == "night":
        return Scene(height_px, width_px, night_scene(height_px, width_px, seed), (), f"procedural night, seed {seed}")
    if kind == "flat":
        level = _number(spec, argument, 0.5, "LEVEL")
        radiance = np.full((height_px, width_px, 3), level, np.float32)
        return Scene(height_px, width_px, radiance, (), f"flat field {level:g}")
    path = Path(spec)
    if path.suffix.lower() != ".exr":
        raise InputError(f"unknown scene {spec!r}: give point[:POWER], pinholes[:POWER[:SPACING]], night, "
                         "flat[:LEVEL] or an .exr file")
    radiance = read_exr(path).rgb()
    if not np.isfinite(radiance).all():
        raise InputError(f"{path}: the scene has NaN or infinite pixels")
    warn_negative_radiance(path, radiance)
    return Scene(height_px, width_px, _cover(radiance, height_px, width_px), (), f"{path.name}")


def pinhole_spacing_for(psf_px: int) -> float:
    """The default pinhole pitch (px) for a camera whose PSF is ``psf_px`` wide: DEFAULT_PINHOLE_SPACING_PX, or
    the PSF with the same margin for the background annulus where it is wider (the A7 profile's 255 px PSF:
    264 px; at 72 px its pinholes were refused as crowded, and the smaller --size the refusal suggested cut the
    PSF's streaks into sources of their own), plus PINHOLE_PITCH_FRACTION_PX: 72.6 and 264.6 px."""
    return max(DEFAULT_PINHOLE_SPACING_PX, psf_px + PINHOLE_MARGIN_PX) + PINHOLE_PITCH_FRACTION_PX


def pinhole_grid(height_px: int, width_px: int, spacing_px: float, power: float, seed: int
                 ) -> tuple[PointSource, ...]:
    """Sources on a rigid square grid ``spacing_px`` apart (a plate's pinholes: one pitch, no pinhole moved on
    its own), the first half a spacing from the top left, the whole grid moved by a seeded offset over a CFA
    period (where a real target sits against the pixels is chance)."""
    def centres(extent_px: int, offset_px: float) -> np.ndarray:  # half a spacing in, as many as fit
        return spacing_px / 2 + offset_px + spacing_px * np.arange(int((extent_px - spacing_px) // spacing_px) + 1)

    offset_y, offset_x = np.random.default_rng(seed).uniform(0, CFA_PERIOD_PX, 2)
    return tuple(PointSource(float(x), float(y), power)
                 for y in centres(height_px, offset_y) for x in centres(width_px, offset_x))


def _number(spec: str, text: str, default: float, what: str) -> float:
    if not text:
        return default
    try:
        value = float(text)
    except ValueError:
        raise InputError(f"scene {spec!r}: {text!r} is not a number") from None
    if not value >= 0 or not np.isfinite(value):
        raise InputError(f"scene {spec!r}: the {what} must be finite and >= 0")
    return value


def _cover(image: np.ndarray, height_px: int, width_px: int) -> np.ndarray:
    """Scale so the image covers the sensor (area averaging when shrinking), then crop the centre."""
    scale = max(height_px / image.shape[0], width_px / image.shape[1])
    size = (max(width_px, round(image.shape[1] * scale)), max(height_px, round(image.shape[0] * scale)))
    interpolation = cv2.INTER_AREA if scale < 1 else cv2.INTER_LINEAR
    resized = cv2.resize(np.ascontiguousarray(image, np.float32), size, interpolation=interpolation)
    top, left = (resized.shape[0] - height_px) // 2, (resized.shape[1] - width_px) // 2
    return np.clip(resized[top:top + height_px, left:left + width_px], 0.0, None)
