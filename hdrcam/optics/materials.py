"""Refractive index of DOE substrates."""

from __future__ import annotations

import numpy as np

# Malitson (1965), fused silica, 0.21-3.71 um: n^2 - 1 = sum B_i l^2 / (l^2 - C_i^2), l and C_i in um.
_FUSED_SILICA_SELLMEIER = ((0.6961663, 0.0684043), (0.4079426, 0.1162414), (0.8974794, 9.896161))


def refractive_index(material: str, wavelength_m: float | np.ndarray) -> float | np.ndarray:
    """Phase refractive index n(lambda) of ``material`` at vacuum wavelength ``wavelength_m`` (metres)."""
    if material != "fused_silica":
        raise ValueError(f"unknown DOE material {material!r}")
    wavelength_um2 = (np.asarray(wavelength_m, dtype=np.float64) * 1e6) ** 2
    n_squared = 1.0 + sum(b * wavelength_um2 / (wavelength_um2 - c * c) for b, c in _FUSED_SILICA_SELLMEIER)
    return np.sqrt(n_squared)


def full_wave_height_m(material: str, wavelength_m: float) -> float:
    """Relief height whose phase delay is one full wave (2 pi) at ``wavelength_m``: lambda / (n(lambda) - 1).

    This is the DOE's h_max (paper Sec. 3.2, Eq. 3) at its design wavelength. Fused silica at 550 nm:
    550 / 0.45991 = 1.1959 um. (1.125 um, the prototype's h_max as the project recorded it for 550 nm, is one
    wave at 519 nm.)
    """
    return float(wavelength_m / (refractive_index(material, wavelength_m) - 1.0))
