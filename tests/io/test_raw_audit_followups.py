"""Follow-ups of the RAW audit: byte counts that overstate the data (Hasselblad 3FR), frames of two bodies in
formats that name no camera (CR3, RAF, ...), the refusal of Quad-Bayer and staggered DNGs named as such, and
greyscale TIFF exports refused as not RAW."""

from __future__ import annotations

import struct

import numpy as np
import pytest
import tifffile

import hdrcam.io.raw as raw_module
from hdrcam.capture.ingest import ingest_folder
from hdrcam.errors import InputError
from hdrcam.hdr.bracket_input import read_bracket
from hdrcam.io.raw import read_raw
from tests.io.realistic_dng import sensor_dn, write_dng


def _scene(height=64, width=96):
    """DN per second above black: a dim left half, a bright right half."""
    radiance = np.full((height, width), 2.0e5)
    radiance[:, width // 2:] = 2.0e6
    return radiance


def _lossless_jpeg(image: np.ndarray, precision: int = 16) -> bytes:
    """A lossless JPEG (SOF3, one component, predictor 1: the sample on the left, the one above at a row's start)
    with one Huffman table giving every difference category 0 to 16 a 5-bit code, as DNG Compression 7 holds."""
    out, bits, pending = bytearray(), 0, 0

    def put(value: int, length: int) -> None:
        nonlocal bits, pending
        bits, pending = (bits << length) | value, pending + length
        while pending >= 8:
            pending -= 8
            out.append((bits >> pending) & 0xFF)
            if out[-1] == 0xFF:
                out.append(0)  # byte stuffing

    samples = image.astype(np.int64)
    for y, row in enumerate(samples):
        for x, sample in enumerate(row):
            predicted = row[x - 1] if x else samples[y - 1, 0] if y else 1 << (precision - 1)
            difference = int(sample - predicted)
            category = abs(difference).bit_length()
            put(category, 5)
            if category:
                put(difference if difference > 0 else difference + (1 << category) - 1, category)
    if pending:
        put((1 << (8 - pending)) - 1, 8 - pending)
    height, width = image.shape
    frame = b"\xff\xc3" + struct.pack(">HBHHBBBB", 11, precision, height, width, 1, 1, 0x11, 0)
    table = b"\xff\xc4" + struct.pack(">HB", 3 + 16 + 17, 0) + bytes([0, 0, 0, 0, 17] + [0] * 11) + bytes(range(17))
    scan = b"\xff\xda" + struct.pack(">HBBBBBB", 8, 1, 1, 0, 1, 0, 0)
    return b"\xff\xd8" + frame + table + scan + bytes(out) + b"\xff\xd9"


def _lossless_dng(path, bayer: np.ndarray, declared_bytes: int | None = None):
    """A DNG of one lossless-JPEG strip (Compression 7) at the end of the file, its StripByteCounts
    ``declared_bytes`` (default: the stream's true length)."""
    write_dng(path, bayer)
    stream = _lossless_jpeg(bayer)
    with tifffile.TiffFile(path, mode="r+b") as tiff:
        page = tiff.pages[0]
        offset = page.dataoffsets[0]
        assert offset + page.databytecounts[0] == tiff.filehandle.size  # the strip ends the file
        page.tags[259].overwrite(7)
        page.tags[279].overwrite(declared_bytes or len(stream))
    path.write_bytes(path.read_bytes()[:offset] + stream)
    return path


def _without_tiff_structure(monkeypatch):
    """As for a CR3, RAF, CRW, ...: tifffile learns nothing, so the camera is "unknown"."""
    monkeypatch.setattr(raw_module, "_tiff_facts", lambda path: raw_module._TiffFacts(file_bytes=path.stat().st_size))


# -- byte counts that overstate the data ----------------------------------------------------------------------------
def test_a_compressed_strip_declaring_its_uncompressed_size_is_read_and_a_cut_copy_refused(tmp_path, capfd):
    """Older Hasselblad 3FRs (CFV, CF132, H3D, H4D) declare width x height x 2 bytes for lossless-JPEG data and
    end long before that (exiftool/exiftool#476); LibRaw decodes them. A copy cut short is still refused in one
    line: LibRaw's lossless-JPEG decoder stops at the end of the file."""
    bayer = sensor_dn(_scene(), 0.004, np.random.default_rng(31))
    path = _lossless_dng(tmp_path / "f.dng", bayer, declared_bytes=bayer.nbytes)
    assert path.stat().st_size < bayer.nbytes
    assert np.array_equal(read_raw(path).bayer_dn, bayer)
    cut = tmp_path / "cut.dng"
    cut.write_bytes(path.read_bytes()[:-800])
    with pytest.raises(InputError, match=r"cut\.dng: truncated or damaged: .*copy it from the card again"):
        read_raw(cut)
    assert capfd.readouterr().err == ""  # LibRaw's own "Unexpected end of file" stays silenced


def test_a_compressed_strip_whose_count_is_not_believed_is_checked_by_its_rows(tmp_path):
    """Without a byte count to trust, a decoder that fills a file's missing rows by repeating one (as Sony's
    does) is caught as for a CR3."""
    bayer = sensor_dn(_scene(), 0.004, np.random.default_rng(32))
    bayer[-9:] = bayer[-10]
    with pytest.raises(InputError, match="truncated or damaged: its last 9 rows repeat one row"):
        read_raw(_lossless_dng(tmp_path / "f.dng", bayer, declared_bytes=bayer.nbytes))


def test_an_uncompressed_strip_needs_its_rows_bytes_whatever_its_count_says(tmp_path):
    """StripByteCounts twice the data (audit exp10): LibRaw reads the rows, so does hdrcam; a copy shorter than
    the rows is refused as before."""
    bayer = sensor_dn(_scene(), 0.004, np.random.default_rng(33))
    path = write_dng(tmp_path / "f.dng", bayer)
    with tifffile.TiffFile(path, mode="r+b") as tiff:
        offset = tiff.pages[0].dataoffsets[0]
        tiff.pages[0].tags[279].overwrite(2 * bayer.nbytes)
    assert np.array_equal(read_raw(path).bayer_dn, bayer)
    cut = tmp_path / "cut.dng"
    cut.write_bytes(path.read_bytes()[:9000])
    with pytest.raises(InputError, match=rf"cut\.dng: truncated or damaged: its image data runs to byte "
                                         rf"{offset + bayer.nbytes} but the file ends at 9000"):
        read_raw(cut)


# -- frames of two bodies in formats that name no camera ------------------------------------------------------------
def _frame(path, exposure_s, rng, white_dn=16383, border=0):
    """A DNG of the 64 x 96 scene; ``border`` masked pixels around it (ActiveArea) make the raw size larger."""
    bayer = sensor_dn(_scene(64 + 2 * border, 96 + 2 * border), exposure_s, rng, clip_dn=min(white_dn, 13500))
    area = [(50829, "I", 4, (border, border, 64 + border, 96 + border), True)] if border else []
    return write_dng(path, bayer, white_dn=white_dn, exposure_s=exposure_s, extra_tags=area)


@pytest.mark.parametrize("other, refusal", [
    ({"white_dn": 15000}, "white level 15000 DN differs from a.dng's 16383 DN"),
    ({"border": 2}, "raw sensor size 100 x 68 px differs from a.dng's 96 x 64 px")])
def test_frames_of_two_bodies_are_refused_where_the_files_name_no_camera(tmp_path, monkeypatch, other, refusal):
    """A CR3's or RAF's camera is "unknown" to hdrcam: what LibRaw reports of the sensor tells the bodies apart."""
    rng = np.random.default_rng(34)
    _frame(tmp_path / "a.dng", 0.002, rng)
    _frame(tmp_path / "b.dng", 0.016, rng, **other)
    _without_tiff_structure(monkeypatch)
    with pytest.raises(InputError, match=rf"b\.dng: {refusal}; a bracket varies only the shutter"):
        read_bracket([tmp_path])


def test_frames_of_one_body_that_names_no_camera_are_a_bracket(tmp_path, monkeypatch):
    rng = np.random.default_rng(35)
    for name, exposure_s in (("a.dng", 0.002), ("b.dng", 0.016)):
        _frame(tmp_path / name, exposure_s, rng, border=2)
    _without_tiff_structure(monkeypatch)
    frames = read_bracket([tmp_path])
    assert [frame.metadata.camera_model for frame in frames] == ["unknown", "unknown"]
    assert [frame.metadata.raw_size_px for frame in frames] == [(100, 68), (100, 68)]


def test_a_bit_depth_mixed_in_frames_naming_no_camera_is_named_as_such(tmp_path, monkeypatch):
    rng = np.random.default_rng(36)
    _frame(tmp_path / "a.dng", 0.002, rng)
    _frame(tmp_path / "b.dng", 0.016, rng, white_dn=4095)
    _without_tiff_structure(monkeypatch)
    with pytest.raises(InputError, match="b.dng: white level 4095 DN, 12 bits where the bracket.s others have 14"):
        read_bracket([tmp_path])


def test_ingest_keeps_two_bodies_that_name_no_camera_apart(tmp_path, monkeypatch):
    rng = np.random.default_rng(37)
    for name, exposure_s, white_dn in (("a1.dng", 0.002, 16383), ("b1.dng", 0.004, 15000),
                                       ("a2.dng", 0.008, 16383), ("b2.dng", 0.016, 15000)):
        _frame(tmp_path / name, exposure_s, rng, white_dn=white_dn)
    _without_tiff_structure(monkeypatch)
    result = ingest_folder(tmp_path)
    assert sorted([frame.path.name for frame in bracket] for bracket in result.brackets) == [["a1.dng", "a2.dng"],
                                                                                              ["b1.dng", "b2.dng"]]


# -- CFAs that are not a square 2 x 2 Bayer tile, named ---------------------------------------------------------------
def test_a_quad_bayer_dng_is_refused_as_quad_bayer(tmp_path):
    """An unremosaiced phone sensor: each colour covers 2 x 2 pixels (CFARepeatPatternDim 4 x 4); LibRaw cannot
    hold the pattern and reports an R/G 2 x 2 tile."""
    bayer = sensor_dn(_scene(), 0.004, np.random.default_rng(38))
    path = write_dng(tmp_path / "quad.dng", bayer, cfa="RRGG" "RRGG" "GGBB" "GGBB")
    with pytest.raises(InputError, match=r"quad\.dng: 4 x 4 Quad-Bayer CFA is not supported"):
        read_raw(path)


def test_another_4_x_4_pattern_is_named_by_its_size_only(tmp_path):
    """Even a Bayer tile written as a 4 x 4 pattern: LibRaw (without the DNG SDK) reads its rows wrongly."""
    bayer = sensor_dn(_scene(), 0.004, np.random.default_rng(39))
    with pytest.raises(InputError, match=r"f\.dng: 4 x 4 CFA is not supported"):
        read_raw(write_dng(tmp_path / "f.dng", bayer, cfa="RGRG" "GBGB" "RGRG" "GBGB"))


def test_a_staggered_dng_is_refused_as_staggered(tmp_path):
    """CFALayout 2 (even columns offset down by half a row, Fuji SuperCCD's DNGs): LibRaw reports a 4 x 4
    pattern over 111 rows of a 64-row file."""
    bayer = sensor_dn(_scene(), 0.004, np.random.default_rng(40))
    path = write_dng(tmp_path / "staggered.dng", bayer, extra_tags=[(50711, "H", 1, (2,), True)])
    with pytest.raises(InputError, match=r"staggered\.dng: staggered CFA layout \(CFALayout 2"):
        read_raw(path)


def test_a_page_with_rows_per_strip_0_keeps_its_byte_count_and_the_dngs_other_facts(tmp_path):
    """RowsPerStrip 0 is invalid TIFF: the page's count is believed (no division by it), so the truncation check
    and the DNG's CFA tags survive it."""
    bayer = sensor_dn(np.full((64, 96), 2.0e5), 0.004, np.random.default_rng(5))
    path = write_dng(tmp_path / "rps0.dng", bayer)
    with tifffile.TiffFile(path, mode="r+b") as tiff:
        tiff.pages[0].tags[278].overwrite(0)
    facts = raw_module._tiff_facts(path)
    assert facts.data_end_bytes > 0 and facts.data_end_checked and facts.cfa_repeat_dim == (2, 2)
    assert np.array_equal(read_raw(path).bayer_dn, bayer)


def test_a_folder_given_as_a_raw_file_is_named_as_a_folder(tmp_path):
    with pytest.raises(InputError, match="a folder, not a RAW file"):
        read_raw(tmp_path)
    with pytest.raises(InputError, match="no such RAW file"):
        read_raw(tmp_path / "missing.ARW")


@pytest.mark.parametrize("cfa", ["RGBG", "RRGB", "GRGB"])
def test_a_two_by_two_tile_of_r_g_b_that_is_no_bayer_layout_is_refused_on_reading(tmp_path, cfa):
    raw = sensor_dn(np.full((64, 96), 5000 / 0.01), 0.01, np.random.default_rng(0), clip_dn=16383)
    with pytest.raises(InputError, match=f"colour filter tile {cfa} is not a Bayer layout"):
        read_raw(write_dng(tmp_path / f"{cfa}.dng", raw, cfa=cfa))  # reconstruct ended with exit 3 in demosaic


def test_a_lens_cap_frame_reads_as_black_and_a_black_level_above_the_data_is_refused(tmp_path):
    from hdrcam.io.ldr_frame import read_ldr_frame
    from hdrcam.io.raw_summary import raw_summary

    capped = write_dng(tmp_path / "cap.dng", np.full((64, 96), 512, np.uint16))
    assert read_ldr_frame(capped).max() == 0.0  # was 0/0: NaN, two lines of error
    assert raw_summary(capped)["clipped_fraction"] == 0.0  # inspect called it 100 % clipped
    dark = np.random.default_rng(2).integers(0, 2, (64, 96)).astype(np.uint16)  # black 0: noise reads 0 and 1 DN
    assert read_ldr_frame(write_dng(tmp_path / "dark.dng", dark, black_dn=(0,) * 4, white_dn=4095)).max() < 0.01
    noisy = np.clip(np.round(512 + np.random.default_rng(1).normal(0, 384, (64, 96))), 0, 16383).astype(np.uint16)
    assert read_ldr_frame(write_dng(tmp_path / "iso204800.dng", noisy)).max() > 0  # read noise is no wrong black
    raw = sensor_dn(np.full((64, 96), 3000 / 0.01), 0.01, np.random.default_rng(0), clip_dn=16383)
    above = write_dng(tmp_path / "above.dng", raw, black_dn=(9000,) * 4)
    with pytest.raises(InputError, match="black level is above its data"):
        read_ldr_frame(above)  # clamped to a black frame, exit 0


def test_a_black_level_above_the_data_is_refused_when_the_frame_is_read_for_fuse_and_calibrate_too(tmp_path):
    raw = sensor_dn(np.full((64, 96), 3000 / 0.01), 0.01, np.random.default_rng(0), clip_dn=16383)
    write_dng(tmp_path / "a.dng", raw, black_dn=(9000,) * 4, exposure_s=0.01)
    write_dng(tmp_path / "b.dng", raw, black_dn=(512,) * 4, exposure_s=0.02)
    with pytest.raises(InputError, match=r"a\.dng: .*black level is above its data"):
        read_bracket([tmp_path])  # fuse and calibrate clamped every sample of a.dng to black and merged it
    one_site = raw.copy()
    one_site[1::2, 0::2] = 100  # one colour site's data below its black level of 512
    with pytest.raises(InputError, match=r"median 100 DN"):
        read_raw(write_dng(tmp_path / "site.dng", one_site))


@pytest.mark.parametrize("top, left", [(1, 0), (0, 1), (1, 1)])
def test_per_site_black_levels_under_an_odd_active_area_origin_are_refused(tmp_path, top, left):
    raw = sensor_dn(np.full((68, 100), 2000 / 0.01), 0.01, np.random.default_rng(0), clip_dn=16383)
    area = [(50829, "I", 4, (top, left, 64 + top, 96 + left), True)]
    with pytest.raises(InputError, match="ActiveArea starts at .* black level differs by colour site"):
        read_raw(write_dng(tmp_path / "odd.dng", raw, black_dn=(500, 540, 580, 520), extra_tags=area))
    read_raw(write_dng(tmp_path / "even.dng", raw, black_dn=(500, 540, 580, 520),
                       extra_tags=[(50829, "I", 4, (2, 0, 66, 96), True)]))  # an even origin reads
    read_raw(write_dng(tmp_path / "one.dng", raw, extra_tags=area))  # one black level for all sites reads


def test_rows_zero_filled_on_the_card_are_refused_as_damage(tmp_path):
    raw = sensor_dn(np.full((64, 96), 3000 / 0.01), 0.01, np.random.default_rng(0), clip_dn=16383)
    raw[40:52] = 0  # inside the file's length: its TIFF strips look whole (inspect and reconstruct took it)
    with pytest.raises(InputError, match=r"damaged: 12 of its rows \(the first at row 40\) hold one value below"):
        read_raw(write_dng(tmp_path / "zeroed.dng", raw))
    with pytest.raises(InputError, match=r"damaged: 12 of its rows"):  # 65535 over 14-bit data: still found
        read_raw(write_dng(tmp_path / "zeroed-65535.dng", raw, white_dn=65535))
    mostly = raw.copy()
    mostly[8:] = 0  # most of the file: named as damage, not as a black level above the data
    with pytest.raises(InputError, match=r"damaged: 56 of its rows"):
        read_raw(write_dng(tmp_path / "mostly.dng", mostly))
    raw[40:52] = 512 + np.random.default_rng(1).integers(-3, 4, (12, 96))  # a black stripe with noise is data
    raw[45, :] = 512  # and so is one flat row at black
    read_raw(write_dng(tmp_path / "dark-stripe.dng", raw))


@pytest.mark.parametrize("make, bits", [("Canon", 16), (None, 16), ("SONY", 8)])
def test_a_raw_developers_greyscale_tiff_export_is_not_raw_and_a_folder_skips_it(tmp_path, make, bits):
    """A black-and-white export (darktable, RawTherapee, Capture One: one 16-bit sample a pixel, BlackIsZero, the
    raw's make and EXIF kept, no CFA or DNG tags): LibRaw decoded it as RGGB mosaic data (or failed on it with a
    data error, which stopped a whole folder); it is refused as not RAW, before LibRaw, so a folder skips it."""
    from hdrcam.io.raw import NotRawError

    image = np.random.default_rng(0).integers(0, 2 ** bits, (64, 96)).astype(np.uint16 if bits == 16 else np.uint8)
    tags = [(271, "s", 0, make, True), (272, "s", 0, f"{make} Body 1", True)] if make else []
    tags.append((33434, "2I", 1, (1, 125), True))  # ExposureTime, which LibRaw reads from any IFD
    export = tmp_path / "export.tif"
    tifffile.imwrite(export, image, photometric="minisblack", software="darktable 4.6.1", extratags=tags,
                     metadata=None)
    with pytest.raises(NotRawError, match="export.tif: a greyscale TIFF image"):
        read_raw(export)
    for exposure in (0.01, 0.04):
        write_dng(tmp_path / f"f{exposure}.dng", sensor_dn(_scene(), exposure, np.random.default_rng(1)),
                  exposure_s=exposure)
    with pytest.warns(UserWarning, match="skipped .*export.tif: a greyscale TIFF image"):
        assert len(read_bracket([tmp_path])) == 2
