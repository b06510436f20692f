"""Colour matrices: sRGB (D65) <-> CIE XYZ, the Sony A7's camera matrix, camera RGB <-> linear sRGB, other
primaries -> Rec. 709."""

from __future__ import annotations

import numpy as np

# red x, y, green x, y, blue x, y, white x, y of Rec. 709 / sRGB (D65), as OpenEXR's chromaticities attribute
REC709_CHROMATICITIES = (0.64, 0.33, 0.30, 0.60, 0.15, 0.06, 0.3127, 0.3290)
CHROMATICITY_TOLERANCE = 1e-3  # of x, y: Rec. 709 / D65 as stored in 32-bit floats or rounded by a writer
# IEC 61966-2-1 sRGB primaries, D65
SRGB_TO_XYZ = np.array([[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722], [0.0193, 0.1192, 0.9505]])
# XYZ (D65) -> camera RGB of the Sony ILCE-7: the matrix LibRaw applies to this model
SONY_A7_XYZ_TO_CAMERA = np.array([[0.5271, -0.0712, -0.0347], [-0.6153, 1.3653, 0.2763], [-0.1601, 0.2366, 0.7242]])


def camera_from_srgb(xyz_to_camera: np.ndarray = SONY_A7_XYZ_TO_CAMERA) -> np.ndarray:
    """3 x 3 linear sRGB -> camera RGB, scaled so white gives the as-shot neutral (max channel 1)."""
    matrix = np.asarray(xyz_to_camera, np.float64) @ SRGB_TO_XYZ
    return matrix / (matrix @ np.ones(3)).max()


def camera_to_srgb_matrix(xyz_to_camera: np.ndarray, as_shot_neutral: np.ndarray) -> np.ndarray:
    """3 x 3 camera RGB -> linear sRGB, white balanced so the as-shot neutral maps to its green value in R, G, B."""
    matrix = np.linalg.inv(np.asarray(xyz_to_camera, np.float64) @ SRGB_TO_XYZ)
    white = matrix @ np.asarray(as_shot_neutral, np.float64)
    return matrix * (as_shot_neutral[1] / white)[:, None] if np.all(white > 0) else matrix


def to_rec709_matrix(chromaticities) -> np.ndarray | None:
    """3 x 3 matrix from linear RGB of these chromaticities (red x, y, green x, y, blue x, y, white x, y) to
    linear Rec. 709 / D65, with Bradford adaptation between the white points (checked against colour-science's
    ``matrix_RGB_to_RGB`` in the tests; numpy only, so a GPU machine's training reads such files), or None when
    they are Rec. 709 / D65 already, absent, or span no gamut (all zero, as some writers store)."""
    if chromaticities is None:
        return None
    values = np.asarray(chromaticities, np.float64)
    if values.shape != (8,) or not np.isfinite(values).all() or \
            np.abs(values - REC709_CHROMATICITIES).max() <= CHROMATICITY_TOLERANCE:
        return None
    primaries, white = values[:6].reshape(3, 2), values[6:]
    if np.any(primaries[:, 1] == 0) or not white[1] > 0:
        return None  # no gamut (all zero): taken as absent
    xyz_columns = np.stack([_xy_to_xyz(xy) for xy in primaries], axis=1)
    if abs(np.linalg.det(xyz_columns)) < 1e-6:
        return None  # collinear primaries: taken as absent
    return np.linalg.inv(_rgb_to_xyz(REC709_CHROMATICITIES)) @ _bradford(white, REC709_CHROMATICITIES[6:]) @ \
        _rgb_to_xyz(values)


def equal_energy_xyz_to_rec709_matrix() -> np.ndarray:
    """3 x 3 matrix from CIE XYZ whose white is equal-energy (x = y = 1/3: Radiance's, as in an XYZE file) to
    linear Rec. 709 / D65, with Bradford adaptation."""
    return np.linalg.inv(_rgb_to_xyz(REC709_CHROMATICITIES)) @ _bradford((1 / 3, 1 / 3), REC709_CHROMATICITIES[6:])


_BRADFORD = np.array([[0.8951, 0.2664, -0.1614], [-0.7502, 1.7135, 0.0367], [0.0389, -0.0685, 1.0296]])


def _xy_to_xyz(xy) -> np.ndarray:
    """XYZ with Y = 1 of a chromaticity (x, y)."""
    x, y = xy
    return np.array([x / y, 1.0, (1 - x - y) / y])


def _rgb_to_xyz(chromaticities) -> np.ndarray:
    """The normalised primary matrix (SMPTE RP 177): RGB of these primaries -> XYZ, white (1, 1, 1) -> its
    white point at Y = 1."""
    values = np.asarray(chromaticities, np.float64)
    primaries = np.stack([_xy_to_xyz(xy) for xy in values[:6].reshape(3, 2)], axis=1)
    return primaries * np.linalg.solve(primaries, _xy_to_xyz(values[6:]))[None, :]


def _bradford(source_white, target_white) -> np.ndarray:
    """XYZ under ``source_white`` -> XYZ under ``target_white`` (x, y each): the Bradford (von Kries) transform."""
    source, target = _BRADFORD @ _xy_to_xyz(source_white), _BRADFORD @ _xy_to_xyz(target_white)
    return np.linalg.inv(_BRADFORD) @ np.diag(target / source) @ _BRADFORD
