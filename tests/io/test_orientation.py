"""A RAW file's orientation flag: read as its EXIF Orientation code (LibRaw's sizes.flip mapped back), the pixels
left in the sensor's orientation, and previews turned upright the way LibRaw turns its own rendering."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
import rawpy
import tifffile

from hdrcam.io.raw import read_raw, read_raw_metadata
from hdrcam.preview import display_oriented
from tests.io.realistic_dng import write_dng


@pytest.mark.parametrize("orientation", range(1, 9))
def test_each_exif_orientation_is_read_and_turned_as_libraw_renders_it(tmp_path, orientation):
    """A bright patch in the sensor's top-left corner (wider than high): LibRaw's own half-size rendering,
    turned by its flip, puts it where display_oriented puts it for the code hdrcam reads."""
    bayer = np.full((32, 48), 712, np.uint16)
    bayer[:8, :12] = 12512
    path = write_dng(tmp_path / "f.dng", bayer, orientation=orientation)
    frame = read_raw(path)
    assert frame.metadata.orientation == orientation
    assert np.array_equal(frame.bayer_dn, bayer)  # the pixels stay as the sensor recorded them
    with rawpy.imread(str(path)) as raw:
        rendered = raw.postprocess(half_size=True, output_bps=8, no_auto_bright=True, gamma=(1, 1),
                                   user_wb=[1, 1, 1, 1], output_color=rawpy.ColorSpace.raw)
    patch = np.zeros((16, 24), bool)  # one rendered pixel per 2 x 2 CFA tile
    patch[:4, :6] = True
    assert np.array_equal(rendered.max(axis=-1) > 64, display_oriented(patch, orientation))


def test_a_file_without_the_tag_is_upright(tmp_path):
    assert read_raw_metadata(write_dng(tmp_path / "f.dng", np.full((32, 48), 712, np.uint16))).orientation == 1


def test_the_real_arw_flagged_portrait_reads_orientation_6_and_the_same_pixels(arw, tmp_path):
    portrait = tmp_path / "portrait.ARW"
    shutil.copyfile(arw, portrait)
    with tifffile.TiffFile(portrait, mode="r+b") as tiff:
        for page in tiff.pages:  # the A7R III writes Orientation 1 in IFD0 and IFD1
            if 274 in page.tags:
                page.tags[274].overwrite(6)
    upright, turned = read_raw(arw), read_raw(portrait)
    assert (upright.metadata.orientation, turned.metadata.orientation) == (1, 6)
    assert (turned.metadata.width_px, turned.metadata.height_px) == (5184, 3464)
    assert np.array_equal(upright.bayer_dn, turned.bayer_dn)
