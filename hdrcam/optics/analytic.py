"""Hand-designed PSFs of the paper's comparisons (Table 2) and of windshield streaks (Sec. 7).

All return float32 arrays (3, S, S), each channel summing to 1, the optical axis at pixel S // 2.
Streaks are rendered by splatting points every 1/4 pixel along each ray with bilinear weights, so
their energy is exact and their position sub-pixel accurate.
"""

from __future__ import annotations

import numpy as np

WINDSHIELD_ROTATION_DEG = ((-8.0, -2.5), (2.5, 8.0))  # paper Sec. 7


def _normalised(channel: np.ndarray) -> np.ndarray:
    return np.repeat((channel / channel.sum())[None], 3, axis=0).astype(np.float32)


def dirac(size_px: int) -> np.ndarray:
    """All energy in the centre pixel (a plain lens, no DOE)."""
    channel = np.zeros((size_px, size_px))
    channel[size_px // 2, size_px // 2] = 1.0
    return _normalised(channel)


def _splat(channel: np.ndarray, rows: np.ndarray, columns: np.ndarray, weights: np.ndarray) -> None:
    size = channel.shape[0]
    row0, column0 = np.floor(rows).astype(int), np.floor(columns).astype(int)
    row_fraction, column_fraction = rows - row0, columns - column0
    for d_row, d_column, weight in ((0, 0, (1 - row_fraction) * (1 - column_fraction)),
                                    (0, 1, (1 - row_fraction) * column_fraction),
                                    (1, 0, row_fraction * (1 - column_fraction)),
                                    (1, 1, row_fraction * column_fraction)):
        r, c = row0 + d_row, column0 + d_column
        inside = (r >= 0) & (r < size) & (c >= 0) & (c < size)
        np.add.at(channel, (r[inside], c[inside]), (weights * weight)[inside])


def star(size_px: int, points: int = 8, centre_fraction: float = 0.94, falloff: float = 1.0,
         angle_deg: float = 0.0, length_px: float | None = None) -> np.ndarray:
    """An n-point star (Rouf et al.'s glare filter): ``points`` rays from the centre at equal angles.

    The centre pixel keeps ``centre_fraction`` of the energy; the rest spreads along the rays with
    intensity ~ r^-falloff up to ``length_px`` (default: to the crop edge). Angle 0 points along +x.
    """
    if not 0.0 <= centre_fraction <= 1.0:
        raise ValueError("centre_fraction must lie in [0, 1]")
    centre = size_px // 2
    length = (size_px - 1) / 2.0 if length_px is None else float(length_px)
    radii = np.arange(1.5, length + 1e-9, 0.25)  # from 1.5 px no splat reaches the centre pixel
    streaks = np.zeros((size_px, size_px))
    for ray in range(points):
        angle = np.deg2rad(angle_deg) + 2.0 * np.pi * ray / points
        _splat(streaks, centre - radii * np.sin(angle), centre + radii * np.cos(angle), radii ** -falloff)
    channel = np.zeros((size_px, size_px))
    if streaks.sum() > 0:
        channel += (1.0 - centre_fraction) * streaks / streaks.sum()
    channel[centre, centre] += centre_fraction if streaks.sum() > 0 else 1.0
    return _normalised(channel)


def dual_peak(size_px: int, offset_px: tuple[int, int] = (0, 8), secondary_fraction: float = 0.06) -> np.ndarray:
    """Two peaks (the Deep Optics heuristic): the main one at the centre, a dimmer copy at ``offset_px``."""
    centre = size_px // 2
    row, column = centre + offset_px[0], centre + offset_px[1]
    if not (0 <= row < size_px and 0 <= column < size_px):
        raise ValueError(f"secondary peak offset {offset_px} lies outside a {size_px} px PSF")
    channel = np.zeros((size_px, size_px))
    channel[centre, centre] = 1.0 - secondary_fraction
    channel[row, column] += secondary_fraction
    return _normalised(channel)


def two_point_star(size_px: int, angle_deg: float, centre_fraction: float = 0.94, falloff: float = 1.0) -> np.ndarray:
    """A single streak through the centre at ``angle_deg`` from the vertical (windshield wiper streaks)."""
    return star(size_px, points=2, centre_fraction=centre_fraction, falloff=falloff, angle_deg=90.0 + angle_deg)


def sample_windshield_angle_deg(rng: np.random.Generator) -> float:
    """A rotation drawn uniformly from (-8, -2.5) U (2.5, 8) degrees (paper Sec. 7)."""
    low, high = WINDSHIELD_ROTATION_DEG[int(rng.integers(2))]
    return float(rng.uniform(low, high))
