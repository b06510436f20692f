"""What hdrcam takes from rawpy, checked against rawpy's documented contract with a stand-in for rawpy.RawPy where
no real file shows it: the colour filter tile at an odd margin (rawpy's raw_pattern starts at the raw data's
origin, margins included)."""

from __future__ import annotations

import datetime as dt
import types

import numpy as np
import pytest
import rawpy

from hdrcam.errors import InputError
from hdrcam.io.raw import read_raw

RGGB_AT_RAW_ORIGIN = np.array([[0, 1], [3, 2]], np.uint8)  # LibRaw colour indices: 0 R, 1 G, 2 B, 3 second G
BLACK_BY_COLOUR = (500, 520, 540, 560)  # DN, black_level_per_channel: indexed by colour, not by tile position


class FakeRawPy:
    """The attributes of rawpy.RawPy that hdrcam reads, for a Bayer file of ``raw_dn`` (raw data, margins
    included) whose visible area starts at ``margins`` (top, left); ``raw_pattern`` is laid out from the raw
    data's origin, as rawpy's ``raw_color`` (full-RAW coordinates) makes it."""

    def __init__(self, raw_dn: np.ndarray, margins: tuple[int, int], visible: tuple[int, int]):
        self.raw_image = raw_dn
        top, left = margins
        height, width = visible
        self.sizes = types.SimpleNamespace(raw_height=raw_dn.shape[0], raw_width=raw_dn.shape[1], height=height,
                                           width=width, top_margin=top, left_margin=left, flip=0, pixel_aspect=1.0)
        self.raw_image_visible = raw_dn[top:top + height, left:left + width]
        self.raw_pattern = RGGB_AT_RAW_ORIGIN
        self.raw_type = rawpy.RawType.Flat
        self.num_colors, self.color_desc = 3, b"RGBG"
        self.black_level_per_channel = list(BLACK_BY_COLOUR)
        self.white_level = 16383
        self.rgb_xyz_matrix = np.vstack([np.eye(3), np.zeros((1, 3))]).astype(np.float32)
        self.camera_whitebalance = [2.0, 1.0, 1.5, 0.0]
        self.other = types.SimpleNamespace(shutter_speed=0.01, iso_speed=100.0, aperture=4.0,
                                           timestamp=dt.datetime(2026, 11, 24, 12))

    def open_file(self, path):
        pass

    def unpack(self):
        pass

    def close(self):
        pass


def _raw_data(height: int, width: int, top: int, left: int) -> np.ndarray:
    """Noise around each site's black level, laid out by RGGB_AT_RAW_ORIGIN from the raw data's origin."""
    colours = np.tile(RGGB_AT_RAW_ORIGIN, (height // 2 + 1, width // 2 + 1))[:height, :width]
    black = np.asarray(BLACK_BY_COLOUR, float)[colours]
    noise = np.random.default_rng(top * 2 + left).normal(40.0, 3.0, (height, width))
    return np.round(black + noise).astype(np.uint16)


@pytest.mark.parametrize("top, left, tile, colours", [(0, 0, "RGGB", (0, 1, 3, 2)), (1, 0, "GBRG", (3, 2, 0, 1)),
                                                       (0, 1, "GRBG", (1, 0, 2, 3)), (1, 1, "BGGR", (2, 3, 1, 0))])
def test_the_cfa_tile_and_its_black_levels_start_at_the_first_visible_pixel(tmp_path, monkeypatch, top, left, tile,
                                                                             colours):
    """A body whose visible area starts on an odd row or column: the tile was raw_pattern[:2, :2], the raw data's
    origin, so every site took another colour's name, black level and white balance."""
    raw_dn = _raw_data(66, 100, top, left)
    monkeypatch.setattr(rawpy, "RawPy", lambda: FakeRawPy(raw_dn, (top, left), (64, 96)))
    path = tmp_path / "odd.raf"  # not TIFF: hdrcam learns nothing from the file's own tags
    path.write_bytes(b"FUJIFILMCCD-RAW " + bytes(112))
    frame = read_raw(path)
    assert frame.metadata.cfa_pattern == tile
    assert frame.metadata.black_level_dn == tuple(float(BLACK_BY_COLOUR[c]) for c in colours)
    site_medians = [float(np.median(frame.bayer_dn[row::2, column::2])) for row in range(2) for column in range(2)]
    assert np.allclose(np.subtract(site_medians, frame.metadata.black_level_dn), 40, atol=2)  # each site's own


IIQ_HEADER = b"IIIIIwaR"  # a Phase One IIQ's first bytes: a byte-order mark, then "RawI" in that order


@pytest.mark.parametrize("header", [IIQ_HEADER, b"II*\x00\x08\x00\x00\x00" + bytes(8) + b"MMMMRawI"])
def test_a_phase_one_iiq_is_refused_before_its_undeveloped_data_is_read(tmp_path, monkeypatch, header):
    """LibRaw reports black 0 for compressed IIQs and subtracts the back's black level (and applies its sensor
    corrections) only when it develops the file: the data, bottoming out at 238 DN on an IQ180 (LibRaw/LibRaw#432),
    were read as signal."""
    raw_dn = np.round(np.random.default_rng(7).normal(260.0, 4.0, (64, 96))).astype(np.uint16)
    fake = FakeRawPy(raw_dn, (0, 0), (64, 96))
    fake.black_level_per_channel = [0, 0, 0, 0]
    monkeypatch.setattr(rawpy, "RawPy", lambda: fake)
    path = tmp_path / "CF000001.IIQ"
    path.write_bytes(header + bytes(120))
    with pytest.raises(InputError, match=r"CF000001\.IIQ: a Phase One IIQ file .* convert it to DNG first"):
        read_raw(path)


def test_a_fuji_superccd_raf_is_refused_by_its_pattern(tmp_path, monkeypatch):
    """Fuji's S-series SuperCCD (LibRaw's fuji_width): the photosites lie on a lattice turned 45 degrees, stored row
    by row, and LibRaw's colour of a stored pixel goes through that turn, so rawpy's raw_pattern repeats every 4
    columns (G B G R / G R G B for RGGB on the turned lattice), not every 2: refused, not read as a Bayer mosaic."""
    raw_dn = np.round(np.random.default_rng(8).normal(600.0, 4.0, (64, 96))).astype(np.uint16)
    fake = FakeRawPy(raw_dn, (0, 0), (64, 96))
    fake.raw_pattern = np.tile(np.array([[1, 2, 3, 0], [3, 0, 1, 2]], np.uint8), (2, 1))
    monkeypatch.setattr(rawpy, "RawPy", lambda: fake)
    path = tmp_path / "DSCF0001.RAF"
    path.write_bytes(b"FUJIFILMCCD-RAW " + bytes(112))
    with pytest.raises(InputError, match=r"DSCF0001\.RAF: colour filter RGBG of 4 x 4 is not a 2 x 2 RGB Bayer"):
        read_raw(path)


@pytest.mark.parametrize("header", [b"II*\x00\x08\x00\x00\x00IIII" + bytes(8), b"MMMM\x00\x00\x00\x00"])
def test_a_byte_order_mark_without_the_iiq_magic_is_no_phase_one_file(tmp_path, header):
    """LibRaw's parse_phase_one returns at once unless "RawI" follows the mark, and the file goes on as TIFF: four
    0x49 bytes among a TIFF's first 32 made hdrcam refuse it as an IIQ."""
    from hdrcam.io.raw import _is_phase_one

    path = tmp_path / "DSC00001.ARW"
    path.write_bytes(header + bytes(120))
    assert not _is_phase_one(path)
