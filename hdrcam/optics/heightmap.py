"""DOE height maps on the fabrication feature grid, and their files.

A height map is an m x m array of heights in metres on square features of pitch ``feature_pitch_m``,
centred on the optical axis: feature f spans [(f - m/2) p, (f - m/2 + 1) p) along each axis.

Parameterisations (paper Sec. 3.2):
- Rank1: Eq. 3, h = h_max * sigmoid(V Q^T) with V, Q in R^(m x r); r = 3 in the paper, r = 1 allowed.
- FreeForm: one parameter per feature, h = h_max * sigmoid(W) (the Deep Optics comparison).
- Fixed: a given map (from a file, a fabrication run, or a flat plate for "no DOE").

Files are single-channel EXRs (channel ``height_m``) with the attribute ``pixel_pitch_m``.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import torch
from torch import nn

from hdrcam.errors import InputError
from hdrcam.io.exr import read_exr, write_exr

HEIGHT_CHANNEL = "height_m"
PITCH_ATTRIBUTE = "pixel_pitch_m"
# Plausible DOE feature pitches (metres): below 0.1 um (a quarter of the shortest visible wavelength) the thin
# scalar element of paper Sec. 3 no longer holds and no lithography writes a camera-sized plate; above 1 mm a
# "feature" spans a large part of any camera DOE (2-10 mm), diffracts by less than lambda / 1 mm (under 0.7 mrad)
# and is a flat plate. The paper's features are 6 um, the simulated profile's 32 um; 6 um written in
# micrometres (6) or millimetres (0.006) falls outside.
FEATURE_PITCH_RANGE_M = (0.1e-6, 1e-3)
# Highest plausible relief (metres): a DOE's heights are a few waves, micrometres (h_max is 1.2 um for one wave
# of fused silica at 550 nm); 100 um is about 84 waves, still far below a height written in micrometres (0.5 um -> 0.5).
MAX_HEIGHT_M = 100e-6


def feature_count(aperture_m: float, feature_pitch_m: float) -> int:
    """Features across the aperture: ceil(D / p)."""
    return math.ceil(aperture_m / feature_pitch_m - 1e-9)


class HeightMap(nn.Module):
    """Base: ``forward()`` returns the m x m heights (metres) at ``feature_pitch_m``."""

    def __init__(self, feature_pitch_m: float):
        super().__init__()
        self.feature_pitch_m = float(feature_pitch_m)


class Rank1HeightMap(HeightMap):
    """h = h_max * sigmoid(V Q^T), V, Q in R^(m x rank) (paper Eq. 3).

    ``init_std`` 0.3 starts near a flat plate that scatters about 6 % of the light, the regulariser's
    target: the phase deviation is ~ 2 pi * std(V Q^T) / 4 ~ 0.25 rad RMS.
    """

    def __init__(self, features: int, feature_pitch_m: float, h_max_m: float, rank: int = 3,
                 init_std: float = 0.3, seed: int = 0, dtype: torch.dtype = torch.float32):
        super().__init__(feature_pitch_m)
        generator = torch.Generator().manual_seed(seed)
        self.h_max_m = float(h_max_m)
        self.v = nn.Parameter(torch.randn(features, rank, generator=generator, dtype=torch.float64).to(dtype) * init_std)
        self.q = nn.Parameter(torch.randn(features, rank, generator=generator, dtype=torch.float64).to(dtype) * init_std)

    def forward(self) -> torch.Tensor:
        return self.h_max_m * torch.sigmoid(self.v @ self.q.T)


class FreeFormHeightMap(HeightMap):
    """h = h_max * sigmoid(W), one parameter per feature."""

    def __init__(self, features: int, feature_pitch_m: float, h_max_m: float, init_std: float = 0.3,
                 seed: int = 0, dtype: torch.dtype = torch.float32):
        super().__init__(feature_pitch_m)
        generator = torch.Generator().manual_seed(seed)
        self.h_max_m = float(h_max_m)
        self.w = nn.Parameter(torch.randn(features, features, generator=generator, dtype=torch.float64).to(dtype)
                              * init_std)

    def forward(self) -> torch.Tensor:
        return self.h_max_m * torch.sigmoid(self.w)


class FixedHeightMap(HeightMap):
    """A given height map (metres); not trainable."""

    def __init__(self, heights_m: np.ndarray | torch.Tensor, feature_pitch_m: float,
                 dtype: torch.dtype = torch.float32):
        super().__init__(feature_pitch_m)
        heights = torch.as_tensor(np.asarray(heights_m, dtype=np.float64)).to(dtype)
        if heights.ndim != 2 or heights.shape[0] != heights.shape[1]:
            raise InputError(f"a height map must be square, got shape {tuple(heights.shape)}")
        if not torch.isfinite(heights).all():
            raise InputError("height map has NaN or Inf values")
        self.register_buffer("heights_m", heights)

    def forward(self) -> torch.Tensor:
        return self.heights_m


def flat_heightmap(aperture_m: float, feature_pitch_m: float, dtype: torch.dtype = torch.float32) -> FixedHeightMap:
    """A plate of zero height: the clear-aperture ("no DOE") case."""
    count = feature_count(aperture_m, feature_pitch_m)
    return FixedHeightMap(np.zeros((count, count)), feature_pitch_m, dtype=dtype)


def feature_indices(coordinates_m: np.ndarray, features: int, feature_pitch_m: float) -> torch.Tensor:
    """Index of the feature under each coordinate (nearest-neighbour sampling of a piecewise-constant map)."""
    index = np.floor(coordinates_m / feature_pitch_m + features / 2.0).astype(np.int64)
    return torch.from_numpy(np.clip(index, 0, features - 1))


def sample_heightmap(heights_m: torch.Tensor, indices: torch.Tensor) -> torch.Tensor:
    """Heights at the simulation grid: heights[iy][:, ix] with the same indices on both axes."""
    return heights_m.index_select(0, indices).index_select(1, indices)


def check_covers_aperture(heights_shape: tuple[int, ...], feature_pitch_m: float, aperture_m: float,
                          source: str) -> None:
    """Refuse a centred map narrower than the aperture diameter."""
    extent_m = min(heights_shape) * feature_pitch_m
    if extent_m < aperture_m * (1 - 1e-6):
        raise InputError(f"{source}: height map spans {extent_m * 1e3:.4g} mm but the aperture is "
                         f"{aperture_m * 1e3:.4g} mm wide; it must cover the aperture")


def load_heightmap(path: Path, aperture_m: float, dtype: torch.dtype = torch.float32) -> FixedHeightMap:
    """Read a height-map EXR (single channel, metres, attribute ``pixel_pitch_m``)."""
    image = read_exr(Path(path))
    pitch = image.attributes.get(PITCH_ATTRIBUTE)
    if not isinstance(pitch, (int, float)) or not pitch > 0:
        raise InputError(f"{path}: height map lacks a positive '{PITCH_ATTRIBUTE}' attribute (metres)")
    low, high = FEATURE_PITCH_RANGE_M
    if not low <= pitch <= high:  # also refuses inf; NaN failed `pitch > 0`
        raise InputError(f"{path}: '{PITCH_ATTRIBUTE}' {pitch:g} m is outside {low * 1e6:g} um .. {high * 1e3:g} mm, "
                         "not a DOE feature; the attribute is the feature pitch in metres (6 um is 6e-6)")
    heights = image.single()
    if not np.isfinite(heights).all():
        raise InputError(f"{path}: height map has NaN or Inf values")
    lowest, highest = float(heights.min()), float(heights.max())
    if lowest < -1e-12 or highest > MAX_HEIGHT_M:  # a picometre below zero is rounding, as in fabrication
        raise InputError(f"{path}: heights span {lowest:.4g} .. {highest:.4g} m, outside 0 .. {MAX_HEIGHT_M * 1e6:g} "
                         "um; heights are metres above the lowest etch level, and a DOE's relief is micrometres "
                         "(1.2 um is 1.2e-6, not 1.2)")
    check_covers_aperture(heights.shape, float(pitch), aperture_m, str(path))
    if heights.shape[0] != heights.shape[1]:
        raise InputError(f"{path}: height map must be square, got {heights.shape}")
    return FixedHeightMap(heights, float(pitch), dtype=dtype)


def save_heightmap(path: Path, heights_m: np.ndarray, feature_pitch_m: float, *, overwrite: bool = False,
                   attributes: dict | None = None) -> Path:
    """Write a height map EXR (float32 metres) with its pitch."""
    return write_exr(path, np.asarray(heights_m, dtype=np.float32), channel_names=(HEIGHT_CHANNEL,),
                     attributes={PITCH_ATTRIBUTE: float(feature_pitch_m), **(attributes or {})},
                     overwrite=overwrite)


def heightmap_for_doe(doe, choice: str, *, seed: int = 0, dtype: torch.dtype = torch.float32) -> HeightMap:
    """The height map a command asks for: 'rank1' or 'freeform' (seeded, untrained initialisation), 'none'
    (flat plate) or the path of a height-map EXR. ``doe`` is a :class:`hdrcam.profiles.DoeSpec`."""
    features = feature_count(doe.aperture_m, doe.feature_size_m)
    if choice == "rank1":
        return Rank1HeightMap(features, doe.feature_size_m, doe.h_max_m, rank=doe.rank, seed=seed, dtype=dtype)
    if choice == "freeform":
        return FreeFormHeightMap(features, doe.feature_size_m, doe.h_max_m, seed=seed, dtype=dtype)
    if choice == "none":
        return flat_heightmap(doe.aperture_m, doe.feature_size_m, dtype=dtype)
    return load_heightmap(Path(choice), doe.aperture_m, dtype=dtype)
