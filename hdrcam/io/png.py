"""PNG output for previews and fabrication masks (8 or 16 bit, grey or RGB), written atomically."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from hdrcam.io.atomic import write_bytes_atomic


def write_png(path: Path, image: np.ndarray, *, overwrite: bool = False) -> Path:
    """Write an H x W (grey) or H x W x 3 (RGB order) uint8/uint16 image."""
    return write_bytes_atomic(Path(path), encoded_png(image, path), overwrite=overwrite)


def encoded_png(image: np.ndarray, path: Path | str = "image") -> bytes:
    """The PNG file of an H x W (grey) or H x W x 3 (RGB order) uint8/uint16 image (``path`` names it in errors)."""
    image = np.asarray(image)
    if image.dtype not in (np.uint8, np.uint16):
        raise ValueError(f"PNG needs uint8 or uint16 pixels, got {image.dtype}")
    if image.ndim == 3:
        image = cv2.cvtColor(image, cv2.COLOR_RGB2BGR)
    ok, encoded = cv2.imencode(".png", image)
    if not ok:
        raise ValueError(f"could not encode {path} as PNG")
    return encoded.tobytes()
