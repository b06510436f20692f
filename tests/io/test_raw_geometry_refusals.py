"""Sensors that are not a 2 x 2 Bayer mosaic on a square grid, named as such: a DNG's Nona-Bayer CFA (which LibRaw
takes for X-Trans), a visible area LibRaw places outside its raw data; and non-square pixels, which are read as stored."""

from __future__ import annotations

import numpy as np
import pytest

import hdrcam.io.raw as raw_module
from hdrcam.errors import InputError
from hdrcam.io.raw import read_raw
from tests.io.realistic_dng import XTRANS, sensor_dn, write_dng


def _bayer(seed: int, height: int = 60, width: int = 96) -> np.ndarray:
    return sensor_dn(np.full((height, width), 2.0e5), 0.004, np.random.default_rng(seed))


def test_a_nona_bayer_dng_is_refused_as_nona_bayer_not_x_trans(tmp_path):
    """Each colour of a 2 x 2 Bayer tile on 3 x 3 pixels (CFARepeatPatternDim 6 x 6): LibRaw reports a 6 x 6
    pattern, as for X-Trans."""
    path = write_dng(tmp_path / "nona.dng", _bayer(50), cfa="RRRGGG" * 3 + "GGGBBB" * 3)
    with pytest.raises(InputError, match=r"nona\.dng: 6 x 6 Nona-Bayer CFA is not supported"):
        read_raw(path)


def test_an_x_trans_dng_is_still_named_x_trans(tmp_path):
    path = write_dng(tmp_path / "xtrans.dng", _bayer(51), cfa=XTRANS, make="Fujifilm", model="X-T3")
    with pytest.raises(InputError, match=r"xtrans\.dng: 6 x 6 X-Trans CFA is not supported"):
        read_raw(path)


def test_a_visible_area_outside_the_raw_data_is_refused(tmp_path, monkeypatch):
    """A staggered layout (CFALayout 2: LibRaw reports 111 x 112 visible pixels of 64 x 96 raw ones, as for a Fuji
    SuperCCD) in a file whose TIFF tags hdrcam does not read (a RAF is not TIFF)."""
    path = write_dng(tmp_path / "superccd.dng", _bayer(52, 64), extra_tags=[(50711, "H", 1, (2,), True)])
    monkeypatch.setattr(raw_module, "_tiff_facts", lambda path: raw_module._TiffFacts(file_bytes=path.stat().st_size))
    with pytest.raises(InputError, match=r"superccd\.dng: LibRaw's visible area \(112 x 111 px from column 0, row 0\) "
                                         r"does not fit in its raw data \(96 x 64 px\)"):
        read_raw(path)


def test_non_square_pixels_are_read_as_stored(tmp_path):
    """DNG DefaultScale 2 : 1 (pixels twice as tall as wide, a Nikon D1X's kind; LibRaw's pixel_aspect 2): the merge
    works per pixel, so the frame is read as stored (not stretched, not refused)."""
    bayer = _bayer(53)
    path = write_dng(tmp_path / "tall.dng", bayer, extra_tags=[(50718, "2I", 2, (2, 1, 1, 1), True)])
    assert read_raw(path).bayer_dn.shape == bayer.shape
