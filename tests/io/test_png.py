"""PNG output is lossless: every 8- and 16-bit grey or RGB image reads back exactly, in RGB order."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from hdrcam.io.png import write_png


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
@pytest.mark.parametrize("shape", [(37, 53), (37, 53, 3)])
def test_png_reads_back_exactly(tmp_path, dtype, shape):
    rng = np.random.default_rng(0)
    noise = rng.integers(0, np.iinfo(dtype).max, shape, dtype=dtype, endpoint=True)
    ramp = np.linspace(0, np.iinfo(dtype).max, noise.size).round().astype(dtype).reshape(shape)
    for name, image in (("noise", noise), ("ramp", ramp)):
        read = cv2.imread(str(write_png(tmp_path / f"{name}.png", image)), cv2.IMREAD_UNCHANGED)
        if image.ndim == 3:
            read = cv2.cvtColor(read, cv2.COLOR_BGR2RGB)
        assert read.dtype == dtype
        np.testing.assert_array_equal(read, image)


def test_png_refuses_pixels_it_cannot_hold(tmp_path):
    with pytest.raises(ValueError, match="uint8 or uint16"):
        write_png(tmp_path / "float.png", np.zeros((4, 4), np.float32))
    assert list(tmp_path.iterdir()) == []
