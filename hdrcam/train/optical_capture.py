"""The simulated camera a network trains through: DOE height map -> PSF -> sensor (paper Eqs. 1-8).

Either the DOE is trained (``rank1`` or ``freeform`` height map, PSF from the wave-optics model of the
profile's optics, recomputed every step so gradients reach the height map), or the PSF is fixed: one of
the paper's hand-designed comparisons (``dirac``, ``star8``, ``dual-peak``, Table 2) or a PSF EXR such as
a calibration record's measured psf.exr. ``windshield`` draws a new 2-point star (a windshield streak)
for every batch, rotated by an angle from (-8, -2.5) U (2.5, 8) degrees (paper Sec. 7).

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
from hdrcam.optics.energy import centre_energy_fraction
from hdrcam.optics.psf import OpticalSetup, PsfResult, PsfSimulator
from hdrcam.optics.psf_file import load_psf
from hdrcam.profiles import Profile
from hdrcam.sensor import Sensor

TRAINABLE_DOES = ("rank1", "freeform")
FIXED_PSFS = ("dirac", "star8", "dual-peak", "windshield")
WINDSHIELD_REFERENCE_DEG = 5.0  # the angle of the PSF stored with a windshield model


def fixed_psf(choice: str, size_px: int) -> np.ndarray:
    """A hand-designed PSF of the paper's Table 2 (``size_px`` square) or a PSF EXR file."""
    if choice == "dirac":
        return dirac(size_px)
    if choice == "star8":
        return star(size_px, points=8)
    if choice == "dual-peak":
        return dual_peak(size_px)
    if choice == "windshield":
        return two_point_star(size_px, WINDSHIELD_REFERENCE_DEG)
    return load_psf(Path(choice))


class OpticalCapture(nn.Module):
    """Radiance (N, 3, H + 2m, W + 2m) -> LDR frame (N, 3, H, W) in [0, 1] with shot/read noise and ADC."""

    def __init__(self, profile: Profile, *, doe: str | None = None, psf: np.ndarray | None = None,
                 seed: int = 0, windshield: bool = False):
        super().__init__()
        self.windshield = windshield
        if (doe is None) == (psf is None):
            raise ValueError("give either a trainable DOE or a fixed PSF")
        self.sensor = Sensor.from_camera(profile.camera)
        self.energy_target = None  # (boxes, 3) energy fractions the regulariser asks of a trainable DOE
        if doe is not None:
            if doe not in TRAINABLE_DOES:
                raise ValueError(f"trainable DOE must be one of {TRAINABLE_DOES}, got {doe!r}")
            self.simulator = PsfSimulator(OpticalSetup.from_profile(profile), heightmap_for_doe(profile.doe, doe,
                                                                                                 seed=seed))
            self.psf_size_px = self.simulator.setup.psf_size_px
            self.energy_boxes_px = energy_boxes_px(profile)
            self.energy_target = energy_targets(self.simulator, self.energy_boxes_px, profile.simulation.energy_target)
        else:
            self.simulator = None
            self.register_buffer("fixed", torch.from_numpy(np.ascontiguousarray(psf, dtype=np.float32)))
            self.psf_size_px = int(psf.shape[-1])

    @property
    def margin_px(self) -> int:
        return self.psf_size_px // 2

    def psf(self) -> tuple[torch.Tensor, torch.Tensor | None]:
        """(3, S, S) PSF with unit sum per channel, and its (boxes, 3) energy fractions (None when fixed)."""
        if self.simulator is None:
            return self.fixed, None
        result = self.simulator()
        return result.psf, box_energy_fractions(result, self.energy_boxes_px)

    def forward(self, radiance: torch.Tensor, generator: torch.Generator | None = None
                ) -> tuple[torch.Tensor, torch.Tensor | None]:
        psf, energy_fractions = self.psf()
        if self.windshield and self.training:
            psf = torch.from_numpy(two_point_star(self.psf_size_px, _windshield_angle_deg(generator))).to(psf)
        captured = self.sensor.capture(radiance, psf, generator=generator, differentiable=True)
        margin = self.margin_px
        return captured[..., margin:captured.shape[-2] - margin, margin:captured.shape[-1] - margin], energy_fractions


def energy_boxes_px(profile: Profile) -> tuple[int, ...]:
    """Half-widths of the boxes whose energy the regulariser holds: the centre, then the guard box if any."""
    guard = profile.simulation.energy_guard_radius_px
    return (profile.simulation.energy_centre_radius_px,) + (() if guard is None else (guard,))


def box_energy_fractions(result: PsfResult, boxes_px: tuple[int, ...]) -> torch.Tensor:
    """(boxes, 3): the energy in each (2r + 1)^2 box about the axis over all the energy reaching the sensor."""
    rows = [result.centre_energy_fraction]
    rows += [centre_energy_fraction(result.psf, radius) * result.crop_energy_fraction for radius in boxes_px[1:]]
    return torch.stack(rows)


def energy_targets(simulator: PsfSimulator, boxes_px: tuple[int, ...], keep_fraction: float) -> torch.Tensor:
    """(boxes, 3) targets of the energy regulariser (paper Sec. 3.3), relative to the bare lens.

    The paper keeps 94 % of the energy in the PSF centre with an f/5.5 lens whose diffraction spot fits in a
    pixel, so there 94 % of the centre is 94 % of everything and the DOE spreads the other 6 % as streaks. A
    slower simulated lens loses a few per cent outside the centre to its own Airy rings before any DOE (profile
    ``simulated``, f/9.8: 94-96 % in 7 x 7 pixels), and an absolute 94 % target leaves the DOE almost nothing to
    spread. So the centre's target is ``keep_fraction`` (0.94) of what the bare lens (the DOE's aperture, no
    relief) keeps there. A guard box, when the profile sets one, must lose that same spread light too: without
    it the cheapest design met the centre target with a ring just outside the 7 x 7 box (a 2000-step run: the
    green PSF at 4 px was 1.6e-3, 0.15e-3 for the bare lens), which only widens the clipped halo round every
    highlight; the guard sends the spread light beyond it, where streaks are distinguishable from the blob.
    """
    with torch.no_grad():
        bare = box_energy_fractions(simulator(heights_m=torch.zeros_like(simulator.heightmap())), boxes_px)
    return bare - (1.0 - keep_fraction) * bare[0]


def _windshield_angle_deg(generator: torch.Generator | None) -> float:
    """Uniform over (-8, -2.5) U (2.5, 8) degrees, drawn from ``generator``."""
    side, position = torch.rand(2, generator=generator).tolist()
    low, high = WINDSHIELD_ROTATION_DEG[int(side * 2)]
    return low + (high - low) * position


def capture_scene(scene: np.ndarray, psf: np.ndarray, profile: Profile, seed: int = 0) -> np.ndarray:
    """Render one frame: an (H + 2m) x (W + 2m) x 3 scene (m = PSF size // 2) -> H x W x 3 capture in [0, 1]."""
    capture = OpticalCapture(profile, psf=psf)
    with torch.no_grad():
        frame, _ = capture(torch.from_numpy(np.ascontiguousarray(scene, np.float32)).permute(2, 0, 1)[None],
                           torch.Generator().manual_seed(seed))
    return frame[0].permute(1, 2, 0).numpy()
