"""The simulated camera a network trains through: DOE height map -> PSF -> sensor (paper Eqs. 1-6).

Either the DOE is trained (``rank1`` or ``freeform`` height map, PSF from the wave-optics model of the
profile's optics, recomputed every step so gradients reach the height map), or the PSF is fixed: one of
the paper's hand-designed comparisons (``dirac``, ``star8``, ``dual-peak``, Table 2) or a PSF EXR such as
a calibration record's measured psf.exr. A hand-designed PSF is what its DOE would make in this camera:
the pattern convolved with the profile's bare-lens PSF (:func:`through_bare_lens`), so ``dirac`` is the
camera with no DOE, and every row of Table 2 shares the lens's diffraction blur. ``windshield`` draws a
new 2-point star (a windshield streak) for every batch, rotated by an angle from (-8, -2.5) U (2.5, 8)
degrees (paper Sec. 7); it stays pixel-sharp, as its network was trained.

Scenes come in padded by ``margin_px`` = PSF size // 2 on every side; the captured frame is the centre,
so light from outside the crop spreads into it as it would on a full sensor.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch
from torch import nn

from hdrcam.optics.analytic import WINDSHIELD_ROTATION_DEG, dirac, dual_peak, star, two_point_star
from hdrcam.optics.heightmap import heightmap_for_doe
from hdrcam.optics.psf import OpticalSetup, PsfResult, PsfSimulator
from hdrcam.optics.psf_file import load_psf
from hdrcam.profiles import Profile
from hdrcam.sensor import Sensor, fft_convolve
from hdrcam.train.choices import TRAINABLE_DOES

WINDSHIELD_REFERENCE_DEG = 5.0  # the angle of the PSF stored with a windshield model


DOE_PATTERNS = {"dirac": dirac, "star8": lambda size_px: star(size_px, points=8), "dual-peak": dual_peak}


def fixed_psf(choice: str, profile: Profile) -> np.ndarray:
    """The (3, S, S) PSF of a fixed-PSF run, S = the profile's PSF size: a hand-designed DOE of the paper's
    Table 2 through the profile's bare lens, the windshield streak (Sec. 7) or a PSF EXR file."""
    size_px = profile.simulation.psf_size_px
    if choice in DOE_PATTERNS:
        return through_bare_lens(DOE_PATTERNS[choice](size_px), profile)
    if choice == "windshield":
        return two_point_star(size_px, WINDSHIELD_REFERENCE_DEG)
    return load_psf(Path(choice), pixel_pitch_m=profile.camera.pixel_pitch_m)


def through_bare_lens(pattern: np.ndarray, profile: Profile) -> np.ndarray:
    """(3, S, S) unit-sum DOE pattern convolved with the profile's bare-lens PSF (the DOE's aperture with no
    relief, same S), cropped to S around the axis and renormalised to unit sum per channel.

    The hand-designed PSFs are drawn on the pixel grid, sharper than any lens can image: the ``simulated``
    profile's f/9.8 lens keeps only 0.53 / 0.66 / 0.80 (R/G/B) of a point's light in its centre pixel (its
    default Fresnel grid; the Airy pattern integrated over the pixel: 0.49 / 0.60 / 0.72, hdrcam.optics.grid). Without
    this, a "Dirac" baseline would be a diffraction-free camera and the learned DOEs, simulated through the
    real aperture, would be compared with a sharper lens rather than with no DOE.
    """
    lens = bare_lens(profile).psf
    with torch.no_grad():
        blurred = fft_convolve(torch.from_numpy(np.ascontiguousarray(pattern, np.float32)).to(lens), lens)
    blurred = blurred.clamp(min=0.0)  # FFT round-off around zero
    return (blurred / blurred.sum(dim=(-2, -1), keepdim=True)).float().numpy()


class OpticalCapture(nn.Module):
    """Radiance (N, 3, H + 2m, W + 2m) -> LDR frame (N, 3, H, W) in [0, 1] with shot/read noise and ADC."""

    def __init__(self, profile: Profile, *, doe: str | None = None, psf: np.ndarray | None = None,
                 seed: int = 0, windshield: bool = False):
        super().__init__()
        self.windshield = windshield
        if (doe is None) == (psf is None):
            raise ValueError("give either a trainable DOE or a fixed PSF")
        self.sensor = Sensor.from_camera(profile.camera)
        self.energy_target = None  # (3,) centre energy fraction the regulariser asks of a trainable DOE
        if doe is not None:
            if doe not in TRAINABLE_DOES:
                raise ValueError(f"trainable DOE must be one of {TRAINABLE_DOES}, got {doe!r}")
            self.simulator = PsfSimulator(OpticalSetup.from_profile(profile), heightmap_for_doe(profile.doe, doe,
                                                                                                 seed=seed))
            self.psf_size_px = self.simulator.setup.psf_size_px
            self.energy_target = profile.simulation.energy_target * bare_lens(profile).centre_energy_fraction
        else:
            self.simulator = None
            self.register_buffer("fixed", torch.from_numpy(np.ascontiguousarray(psf, dtype=np.float32)))
            self.psf_size_px = int(psf.shape[-1])

    @property
    def margin_px(self) -> int:
        return self.psf_size_px // 2

    def psf(self) -> tuple[torch.Tensor, torch.Tensor | None]:
        """(3, S, S) PSF with unit sum per channel, and the centre energy fraction (None when fixed)."""
        if self.simulator is None:
            return self.fixed, None
        result = self.simulator()
        return result.psf, result.centre_energy_fraction

    def forward(self, radiance: torch.Tensor, generator: torch.Generator | None = None
                ) -> tuple[torch.Tensor, torch.Tensor | None]:
        psf, centre_fraction = self.psf()
        if self.windshield and self.training:
            psf = torch.from_numpy(two_point_star(self.psf_size_px, _windshield_angle_deg(generator))).to(psf)
        captured = self.sensor.capture(radiance, psf, generator=generator, differentiable=True)
        margin = self.margin_px
        return captured[..., margin:captured.shape[-2] - margin, margin:captured.shape[-1] - margin], centre_fraction


def bare_lens(profile: Profile) -> PsfResult:
    """The profile's lens behind the DOE's aperture with no relief: its PSF and centre energy fraction.

    Two things rest on it. Hand-designed PSFs are imaged through it (:func:`through_bare_lens`). And the
    regulariser's target is ``energy_target`` (0.94) times its centre fraction: the paper keeps 94 % of the
    energy in the PSF centre (Sec. 3.3) with an f/5.5 lens whose diffraction spot fits in a pixel, so there 94 %
    of the centre is 94 % of everything and the DOE spreads the other 6 %. A slower simulated lens loses a few
    per cent outside the centre to its own Airy rings before any DOE (profile ``simulated``, f/9.8: 94-96 % in
    7 x 7 pixels), and an absolute 94 % target leaves the DOE almost nothing to spread: a 2000-step design under
    it ended at 0.933/0.940/0.941 (R/G/B) against 0.943/0.954/0.962 for the bare lens.
    """
    simulator = PsfSimulator(OpticalSetup.from_profile(profile), heightmap_for_doe(profile.doe, "none"))
    with torch.no_grad():
        return simulator()


def _windshield_angle_deg(generator: torch.Generator | None) -> float:
    """Uniform over (-8, -2.5) U (2.5, 8) degrees, drawn from ``generator``."""
    side, position = torch.rand(2, generator=generator).tolist()
    low, high = WINDSHIELD_ROTATION_DEG[int(side * 2)]
    return low + (high - low) * position


CAPTURE_BYTES_PER_PIXEL = 300  # capture_scene with its scene and frame (measured: 149 bytes a pixel at 1024^2, x 2)


def capture_scene(scene: np.ndarray, psf: np.ndarray, profile: Profile, seed: int = 0) -> np.ndarray:
    """Render one frame: an (H + 2m) x (W + 2m) x 3 scene (m = PSF size // 2) -> H x W x 3 capture in [0, 1]."""
    capture = OpticalCapture(profile, psf=psf)
    with torch.no_grad():
        frame, _ = capture(torch.from_numpy(np.ascontiguousarray(scene, np.float32)).permute(2, 0, 1)[None],
                           torch.Generator().manual_seed(seed))
    return frame[0].permute(1, 2, 0).numpy()
