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


def in_rec709(rgb: np.ndarray, chromaticities) -> np.ndarray:
    """H x W x 3 float32 linear RGB of these ``chromaticities`` in linear Rec. 709 / D65 (:func:`to_rec709_matrix`);
    ``rgb`` itself when no conversion applies."""
    matrix = to_rec709_matrix(chromaticities)
    return rgb if matrix is None else rgb @ matrix.T.astype(np.float32)


def to_rec709_matrix(chromaticities) -> np.ndarray | None:
    """3 x 3 matrix from linear RGB of these chromaticities (red x, y, green x, y, blue x, y, white x, y) to
    linear Rec. 709 / D65, with Bradford adaptation between the white points (equal to colour-science's
    ``matrix_RGB_to_RGB`` to 1e-12, see the tests; numpy only, so a GPU machine's training reads such files), or
    None when they are Rec. 709 / D65 already, absent (None, or not eight numbers), or span no gamut (all zero, as
    some writers store; collinear primaries)."""
    try:
        values = np.asarray(chromaticities, np.float64)
    except (TypeError, ValueError):  # not numbers (an attribute of another type under this name)
        return None
    if values.shape != (8,) or np.abs(values - REC709_CHROMATICITIES).max() <= CHROMATICITY_TOLERANCE:
        return None
    try:
        source = normalised_primary_matrix(values)
    except ValueError:
        return None
    return np.linalg.inv(normalised_primary_matrix(REC709_CHROMATICITIES)) @ \
        _bradford(values[6:], REC709_CHROMATICITIES[6:]) @ source


EQUAL_ENERGY_XYZ_CHROMATICITIES = (1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1 / 3, 1 / 3)  # Radiance's XYZE pixels


def normalised_primary_matrix(chromaticities) -> np.ndarray:
    """3 x 3 RGB -> XYZ of primaries and white (red x, y, green x, y, blue x, y, white x, y; SMPTE RP 177): each
    primary's (x, y, z) scaled so the three sum to the white's XYZ at Y = 1 - no division by a primary's y, so
    CIE XYZ's own primaries (1, 0), (0, 1), (0, 0) work. ValueError for a white point with y <= 0, values that
    are not finite, or primaries on one line."""
    xy = np.asarray(chromaticities, dtype=np.float64).reshape(4, 2)
    white_y = xy[3, 1]
    if not np.all(np.isfinite(xy)) or white_y <= 0:
        raise ValueError(f"chromaticities {tuple(xy.ravel())}: the white point needs y > 0")
    primaries = np.column_stack([xy[:3, 0], xy[:3, 1], 1.0 - xy[:3].sum(axis=1)]).T  # columns: x, y, z
    if abs(np.linalg.det(primaries)) < 1e-12:
        raise ValueError(f"chromaticities {tuple(xy.ravel())}: the primaries lie on one line")
    white = _white_xyz(xy[3])
    return primaries * np.linalg.solve(primaries, white)[None, :]


_BRADFORD = np.array([[0.8951, 0.2664, -0.1614], [-0.7502, 1.7135, 0.0367], [0.0389, -0.0685, 1.0296]])


def _white_xyz(xy) -> np.ndarray:
    """XYZ at Y = 1 of a white point's chromaticity (x, y), y > 0."""
    return np.array([xy[0] / xy[1], 1.0, (1.0 - xy[0] - xy[1]) / xy[1]])


def _bradford(source_white, target_white) -> np.ndarray:
    """XYZ under ``source_white`` -> XYZ under ``target_white`` (x, y each): the Bradford (von Kries) transform."""
    source, target = _BRADFORD @ _white_xyz(source_white), _BRADFORD @ _white_xyz(target_white)
    return np.linalg.inv(_BRADFORD) @ np.diag(target / source) @ _BRADFORD
