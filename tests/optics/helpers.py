"""Small optical setups with analytic answers."""

from __future__ import annotations

import math

from hdrcam.optics.grid import SimulationGrid, is_fast_length
from hdrcam.optics.psf import OpticalSetup
from hdrcam.profiles import image_distance_m


def single_wavelength_setup(*, aperture_m: float, focal_length_m: float, wavelength_m: float = 550e-9,
                            pixel_pitch_m: float = 6e-6, upsample: int = 3, window_m: float | None = None,
                            source_distance_m: float = 5.0, focus_distance_m: float = 5.0,
                            propagation: str = "fresnel", psf_size_px: int = 15) -> OpticalSetup:
    """One wavelength in all three bands; the grid spans ``window_m`` (default: the aperture)."""
    pitch = pixel_pitch_m / upsample
    pixels = math.ceil((window_m or aperture_m) / pitch / upsample)
    while not is_fast_length(pixels * upsample):
        pixels += 1
    grid = SimulationGrid(pixel_pitch_m=pixel_pitch_m, upsample=upsample, sensor_pixels=max(pixels, psf_size_px))
    return OpticalSetup(grid=grid, pixel_pitch_m=pixel_pitch_m, aperture_m=aperture_m, focal_length_m=focal_length_m,
                        sensor_distance_m=image_distance_m(focal_length_m, focus_distance_m),
                        source_distance_m=source_distance_m, material="fused_silica", propagation=propagation,
                        band_wavelengths_m=((wavelength_m,), (wavelength_m,), (wavelength_m,)),
                        psf_size_px=psf_size_px, energy_centre_radius_px=1)
