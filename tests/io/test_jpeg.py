"""JPEG figures: the written file decodes to the image (RGB order kept, within JPEG's loss at quality 95)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from hdrcam.errors import OutputExistsError
from hdrcam.io.jpeg import write_jpeg


def test_a_written_figure_decodes_to_its_pixels_in_rgb_order(tmp_path):
    rows, columns = np.mgrid[:64, :96]
    image = np.stack([rows * 4, columns * 2, np.full_like(rows, 40)], axis=-1).astype(np.uint8)
    path = write_jpeg(tmp_path / "figure.jpg", image)
    decoded = cv2.cvtColor(cv2.imread(str(path)), cv2.COLOR_BGR2RGB)
    assert decoded.shape == image.shape
    assert np.abs(decoded.astype(int) - image).mean() < 1.0  # red stays red: a swapped order errs by ~70
    with pytest.raises(OutputExistsError):
        write_jpeg(path, image)


def test_only_8_bit_rgb_is_written(tmp_path):
    with pytest.raises(ValueError, match="uint8"):
        write_jpeg(tmp_path / "x.jpg", np.zeros((4, 4, 3), np.uint16))
    assert not (tmp_path / "x.jpg").exists()
