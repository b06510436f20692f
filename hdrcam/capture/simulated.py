"""``--camera sim``: a simulated Sony A7 that renders a scene through a PSF and the sensor noise model.

Image formation (paper Eq. 6 with a real sensor's details): camera RGB irradiance = PSF * (colour matrix x
scene), mosaicked through the CFA; photo-electrons are Poisson, read noise Gaussian, hot pixels add dark
charge in proportion to the exposure; the ADC adds the black level (512) and clips at the white level
(14 bit). The shutter lands on the A7's 1/3 EV notches, whose true times (powers of two) differ from their
labels, plus a small per-notch error; the written DNG says the label, like a real camera.

Units: scene radiance 1.0 fills the full well at base ISO in ``reference_exposure_s`` seconds. The profile's
``full_well_e`` is the charge at the white level at base ISO; the pixel itself saturates 5 % higher, so a
clipped pixel reads exactly the white level, as on real cameras whose ADC clips first.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
from pathlib import Path

import numpy as np
import torch

from hdrcam.capture.camera import CapturedFrame, ExposureSettings
from hdrcam.capture.notches import ShutterNotch, iso_setting, nearest_shutter
from hdrcam.capture.scene import Scene
from hdrcam.colorimetry import SONY_A7_XYZ_TO_CAMERA, camera_from_srgb
from hdrcam.errors import InputError
from hdrcam.io.atomic import write_bytes_atomic
from hdrcam.io.dng import dng_bytes
from hdrcam.io.raw import read_raw
from hdrcam.optics.psf_file import load_psf
from hdrcam.optics.subpixel import box_shift, split_position
from hdrcam.profiles import Profile
from hdrcam.sensor import bayer_mosaic, fft_convolve

BASE_ISO = 100
DEFAULT_REFERENCE_EXPOSURE_S = 1.0 / 60.0
FULL_WELL_HEADROOM = 1.05  # pixels hold 5 % more charge than the ADC's white level: clipped pixels read white


@dataclasses.dataclass(frozen=True)
class SensorDefects:
    """Fixed-pattern defects of one simulated sensor (seeded like a serial number)."""

    hot_pixel_rows: np.ndarray
    hot_pixel_columns: np.ndarray
    hot_pixel_rate_per_s: np.ndarray  # dark charge in full wells per second

    @classmethod
    def draw(cls, height_px: int, width_px: int, fraction: float, seed: int) -> "SensorDefects":
        rng = np.random.default_rng([seed, 0x407])
        count = int(round(fraction * height_px * width_px))
        index = rng.choice(height_px * width_px, size=count, replace=False)
        return cls(index // width_px, index % width_px, rng.uniform(0.2, 4.0, count))


class SimulatedCamera:
    """A simulated Sony A7 (Camera protocol). Frames are reproducible from ``seed`` and the capture order."""

    suffix = ".dng"

    def __init__(self, profile: Profile, scene: Scene, psf: np.ndarray, *, seed: int = 0,
                 hot_pixel_fraction: float = 2e-5, exposure_error: float = 0.02,
                 reference_exposure_s: float = DEFAULT_REFERENCE_EXPOSURE_S):
        self.profile, self.scene, self.seed = profile, scene, seed
        self.model = f"Sony ILCE-7 (simulated, {profile.name})"
        self.camera = profile.camera
        if psf.ndim != 3 or psf.shape[0] != 3:
            raise ValueError(f"the PSF must be 3 x k x k, got {psf.shape}")
        self.psf = psf.astype(np.float32)
        check_defect_settings(hot_pixel_fraction, exposure_error)
        self.exposure_error = exposure_error
        self.reference_exposure_s = reference_exposure_s
        self.defects = SensorDefects.draw(scene.height_px, scene.width_px, hot_pixel_fraction, seed)
        self._notch = nearest_shutter(1.0 / 60.0)
        self._iso = BASE_ISO
        self._frames = 0
        self._rates: dict[bool, np.ndarray] = {}

    def __enter__(self) -> "SimulatedCamera":
        return self

    def __exit__(self, *exc) -> None:
        self._rates.clear()

    # -- settings -------------------------------------------------------------------------------------------
    def settings(self) -> ExposureSettings:
        return ExposureSettings(float(self._notch.nominal), self._notch.label, float(self._iso),
                                self.profile.lens.f_number)

    def set_exposure(self, exposure_s: float | None = None, iso: float | None = None) -> ExposureSettings:
        if exposure_s is not None:
            self._notch = nearest_shutter(exposure_s)
        if iso is not None:
            self._iso = iso_setting(iso)
        return self.settings()

    @property
    def notch(self) -> ShutterNotch:
        return self._notch

    def set_notch(self, notch: ShutterNotch) -> None:
        self._notch = notch

    def set_iso(self, iso: int) -> None:
        self._iso = iso

    def true_exposure_s(self, notch: ShutterNotch | None = None) -> float:
        """The time the shutter really stays open at a notch: 2^(k/3) s times a fixed per-notch error."""
        notch = notch or self._notch
        error = np.random.default_rng([self.seed, 0x5407, notch.index]).uniform(-1.0, 1.0) * self.exposure_error
        return notch.true_s * (1.0 + error)

    # -- capture --------------------------------------------------------------------------------------------
    def render_dn(self, *, dark: bool = False) -> np.ndarray:
        """The next frame's Bayer digital numbers (uint16) at the current settings; advances the frame counter."""
        camera = self.camera
        rng = np.random.default_rng([self.seed, self._frames])
        self._frames += 1
        gain = self._iso / BASE_ISO
        exposure = self.true_exposure_s()
        charge = self._rate(dark) * (exposure / self.reference_exposure_s)  # full wells collected
        hot = self.defects
        charge[hot.hot_pixel_rows, hot.hot_pixel_columns] += hot.hot_pixel_rate_per_s * exposure
        capacity_e = camera.full_well_e * FULL_WELL_HEADROOM
        electrons = rng.poisson(np.minimum(charge, 2 * FULL_WELL_HEADROOM) * camera.full_well_e).astype(np.float32)
        electrons = np.minimum(electrons, capacity_e)
        electrons += rng.standard_normal(electrons.shape, dtype=np.float32) * np.float32(camera.read_noise_e)
        dn_per_electron = (camera.white_level_dn - camera.black_level_dn) * gain / camera.full_well_e
        digital = np.rint(camera.black_level_dn + electrons * np.float32(dn_per_electron))
        return np.clip(digital, 0, camera.white_level_dn).astype(np.uint16)

    def capture(self, folder: Path, stem: str, *, dark: bool = False) -> CapturedFrame:
        settings = self.settings()
        timestamp = dt.datetime.now().replace(microsecond=0)
        path = self.write_frame(folder / f"{stem}{self.suffix}", self.render_dn(dark=dark), settings, timestamp)
        return CapturedFrame(path, settings, timestamp, self.model, read_raw(path))

    def write_frame(self, path: Path, bayer_dn: np.ndarray, settings: ExposureSettings,
                    timestamp: dt.datetime) -> Path:
        return write_bytes_atomic(path, self.frame_bytes(bayer_dn, settings, timestamp))

    def frame_bytes(self, bayer_dn: np.ndarray, settings: ExposureSettings, timestamp: dt.datetime) -> bytes:
        """The DNG file a frame is stored in, as the camera would write it."""
        camera = self.camera
        neutral = camera_from_srgb() @ np.ones(3)
        return dng_bytes(bayer_dn, cfa_pattern=camera.cfa_pattern, black_level_dn=camera.black_level_dn,
                         white_level_dn=camera.white_level_dn, xyz_to_camera=SONY_A7_XYZ_TO_CAMERA,
                         as_shot_neutral=tuple(neutral), exposure_s=settings.exposure_s,
                         f_number=settings.f_number, iso=int(settings.iso), timestamp=timestamp,
                         make="Sony", model="ILCE-7")

    # -- rendering ------------------------------------------------------------------------------------------
    def _rate(self, dark: bool) -> np.ndarray:
        """Mosaicked camera irradiance, full wells per reference exposure at base ISO (cached; copied)."""
        if dark not in self._rates:
            scene = self.scene.dark() if dark else self.scene
            self._rates[dark] = bayer_mosaic(torch.from_numpy(camera_irradiance(scene, self.psf)),
                                          self.camera.cfa_pattern).numpy()
        return self._rates[dark].copy()


def check_defect_settings(hot_pixel_fraction: float, exposure_error: float) -> None:
    """InputError unless both are fractions from 0 up to (not including) 1: of the pixels, and the largest
    relative error of a true shutter time."""
    for name, value in (("hot_pixel_fraction", hot_pixel_fraction), ("exposure_error", exposure_error)):
        if not 0 <= value < 1:
            raise InputError(f"{name} {value!r}: expected a fraction from 0 up to (not including) 1")


def camera_irradiance(scene: Scene, psf: np.ndarray) -> np.ndarray:
    """3 x H x W camera-RGB irradiance: PSF * (camera_from_srgb x radiance) plus shifted PSFs of point sources."""
    irradiance = np.zeros((3, scene.height_px, scene.width_px), np.float32)
    if scene.radiance is not None:
        camera_rgb = np.clip(scene.radiance @ camera_from_srgb().T.astype(np.float32), 0.0, None)
        image = torch.from_numpy(np.ascontiguousarray(camera_rgb.transpose(2, 0, 1)))
        irradiance += fft_convolve(image, torch.from_numpy(psf)).numpy()
    mixing = camera_from_srgb()
    for point in scene.points:
        _add_point(irradiance, psf, point.x_px, point.y_px, point.power * np.clip(mixing @ point.colour, 0.0, None))
    if not np.isfinite(irradiance).all():  # float32 sums of the convolution overflow near 3.4e38
        brightest = float(scene.radiance.max()) if scene.radiance is not None else 0.0
        raise InputError(f"the scene's radiance (up to {brightest:.3g}) overflows the simulation's float32 "
                         "arithmetic; scale the scene down (the exposure plan follows its brightness)")
    return np.clip(irradiance, 0.0, None)


def _add_point(irradiance: np.ndarray, psf: np.ndarray, x_px: float, y_px: float, power: np.ndarray) -> None:
    """Add the PSF of a point source whose image lies at (x, y): each channel's pixel-integrated PSF split
    over neighbouring pixels by the box model of :mod:`hdrcam.optics.subpixel` (no ringing, exact energy)."""
    column, fraction_x = split_position(x_px)
    row, fraction_y = split_position(y_px)
    moved = box_shift(psf.astype(np.float64), fraction_y, fraction_x)
    top, left = row - psf.shape[1] // 2, column - psf.shape[2] // 2
    for channel in range(3):
        _add_clipped(irradiance[channel], moved[channel] * power[channel], top, left)


def _add_clipped(target: np.ndarray, patch: np.ndarray, top: int, left: int) -> None:
    """target[top:, left:] += patch, for the part of the patch inside the target."""
    y0, x0 = max(top, 0), max(left, 0)
    y1, x1 = min(top + patch.shape[0], target.shape[0]), min(left + patch.shape[1], target.shape[1])
    if y0 < y1 and x0 < x1:
        target[y0:y1, x0:x1] += patch[y0 - top:y1 - top, x0 - left:x1 - left]


def simulation_psf(profile: Profile, choice: str = "doe", *, seed: int = 0) -> np.ndarray:
    """The PSF a simulated camera sees (3 x k x k, unit sum per channel).

    ``doe``: wave-optics PSF of the profile's DOE (seeded initialisation) for a source at the calibration
    distance; ``dirac``: no DOE blur; otherwise a PSF EXR (e.g. from ``hdrcam psf`` or a calibration record).
    """
    from hdrcam.optics.analytic import dirac
    from hdrcam.optics.heightmap import heightmap_for_doe
    from hdrcam.optics.psf import OpticalSetup, PsfSimulator

    if choice == "dirac":
        return dirac(profile.simulation.psf_size_px)
    if choice == "doe":
        setup = OpticalSetup.from_profile(profile, source_distance_m=profile.calibration.point_source_distance_m)
        simulator = PsfSimulator(setup, heightmap_for_doe(profile.doe, profile.doe.kind, seed=seed))
        with torch.no_grad():
            return simulator().psf.numpy().astype(np.float32)
    return load_psf(Path(choice), pixel_pitch_m=profile.camera.pixel_pitch_m)
