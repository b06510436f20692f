"""Colour matrices: sRGB (D65) <-> CIE XYZ, the Sony A7's camera matrix, camera RGB <-> linear sRGB."""

from __future__ import annotations

import numpy as np

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
