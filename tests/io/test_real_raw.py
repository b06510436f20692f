"""RAW files as real cameras write them: the real Sony A7R III ARW in ../shared/data/raw (skipped when absent)
and DNGs with realistic sensor statistics for what it does not cover (tests/io/realistic_dng.py)."""

from __future__ import annotations

import datetime as dt
import json
import shutil
import struct

import numpy as np
import pytest

from hdrcam.cli import main
from hdrcam.capture.ingest import ingest_folder
from hdrcam.errors import InputError
from hdrcam.hdr.bracket_input import read_bracket
from hdrcam.hdr.fuse import fuse
from hdrcam.hdr.merge import merge_bayer
from hdrcam.io.ldr_frame import read_ldr_frame
from hdrcam.io.raw import NO_COLOUR_MATRIX, read_raw, read_raw_metadata
from hdrcam.io.raw_clipping import channel_clip_level
from hdrcam.io.raw_summary import raw_summary
from hdrcam.profiles import load_profile
from tests.io.realistic_dng import XTRANS, sensor_dn, write_dng

CAMERA = load_profile("simulated").camera


def _scene(height=64, width=96):
    """DN per second above black: a dim left half, a bright right half (clips in the long frame)."""
    radiance = np.full((height, width), 2.0e5)
    radiance[:, width // 2:] = 2.0e6
    return radiance


# -- the real ARW -----------------------------------------------------------------------------------------------
def test_the_real_arw_decodes_as_libraw_does(arw):
    import rawpy

    frame = read_raw(arw)
    with rawpy.imread(str(arw)) as raw:
        assert np.array_equal(frame.bayer_dn, raw.raw_image_visible)  # no flip, no crop, no black subtraction
        assert not raw.color_matrix.any()  # LibRaw's own colour matrix is zero for this file ...
    meta = frame.metadata
    assert (meta.width_px, meta.height_px, meta.cfa_pattern) == (5184, 3464, "RGGB")
    assert meta.black_level_dn == (512.0,) * 4 and meta.white_level_dn == 16383
    assert meta.colour_matrix_source == "LibRaw"  # ... its table for the model is not
    assert abs(np.linalg.det(meta.xyz_to_camera)) > 0.1
    assert (meta.make, meta.camera_model, meta.file_format) == ("SONY", "SONY ILCE-7RM3", "ARW")
    assert (meta.exposure_s, meta.iso, meta.f_number) == (0.0015625, 3200.0, 6.3)
    # cRAW: clipped greens and blues pile up at 16372, below the metadata white, scattered up to 16628 above it;
    # the second green's pile holds 14 samples (19 at or above it), which a 16-sample minimum missed; red's two
    # brightest samples sit at 16372 too - too few for a pile of its own, they take the positions' shared one
    assert frame.clip_level_tile_dn.tolist() == [[16372, 16372], [16372, 16372]]
    assert frame.bayer_dn.max() == 16628



def test_the_frame_is_a_read_only_view_that_outlives_the_reader(arw):
    """read_raw keeps LibRaw's buffer instead of copying it: the frame's data stay valid after the reader is gone
    and after a collection, and cannot be written by mistake."""
    import gc

    import rawpy

    frame = read_raw(arw)
    gc.collect()
    with rawpy.imread(str(arw)) as raw:
        assert np.array_equal(frame.bayer_dn, raw.raw_image_visible)
    with pytest.raises(ValueError, match="read-only"):
        frame.bayer_dn[0, 0] = 0

def test_inspect_prints_one_json_line_per_file_and_refuses_a_truncated_copy(arw, tmp_path, capsys):
    half = tmp_path / "half.ARW"
    half.write_bytes(arw.read_bytes()[:arw.stat().st_size // 2])
    assert main(["inspect", str(arw), str(half)]) == 1
    out, err = capsys.readouterr()
    lines = out.splitlines()
    assert len(lines) == 1
    summary = json.loads(lines[0])
    assert summary["model"] == "SONY ILCE-7RM3" and summary["format"] == "ARW" and summary["cfa"] == "RGGB"
    assert summary["clip_level_dn"] == [16372.0] * 4 and summary["clip_below_white"]
    assert 0 < summary["clipped_fraction"] < 1e-4 and summary["colour_matrix_source"] == "LibRaw"
    assert err.count("\n") == 1 and "half.ARW" in err and "truncated" in err
    with pytest.raises(InputError, match="truncated"):
        read_ldr_frame(half)  # reconstruct's reader refuses it too (LibRaw alone would fill the missing rows)


def test_a_copy_cut_inside_its_preview_is_refused_by_its_byte_counts(arw, tmp_path):
    """Cut at byte 146000, before IFD0's preview JPEG: tifffile cannot read that JPEG's size, so IFD0 states none;
    its count is then believed (the page must not end the byte-count check: the cut file decodes to zeros)."""
    cut = tmp_path / "cut.ARW"
    cut.write_bytes(arw.read_bytes()[:146000])
    with pytest.raises(InputError, match=r"truncated or damaged: its image data runs to byte 18649856"):
        read_raw(cut)


def test_a_truncated_file_without_tiff_structure_is_caught_by_its_repeated_rows(arw, tmp_path, monkeypatch):
    """For formats that are not TIFF (CR3, RAF, ...) only the data tells: LibRaw repeats the last decoded row."""
    import hdrcam.io.raw as raw_module

    def no_tiff_structure(path):
        return raw_module._TiffFacts(file_bytes=path.stat().st_size)

    monkeypatch.setattr(raw_module, "_tiff_facts", no_tiff_structure)
    cut = tmp_path / "cut.ARW"
    cut.write_bytes(arw.read_bytes()[:int(arw.stat().st_size * 0.97)])
    with pytest.raises(InputError, match="last 107 rows repeat"):
        read_raw(cut)
    assert read_raw(arw).bayer_dn.shape == (3464, 5184)  # the whole file has no repeated row


def test_repeated_rows_count_only_when_the_row_is_not_flat():
    from hdrcam.io.raw import repeated_tail_rows

    rows = np.arange(60, dtype=np.uint16).reshape(12, 5)
    assert repeated_tail_rows(rows) == 0
    rows[7:] = rows[6]
    assert repeated_tail_rows(rows) == 5
    rows[7:] = 16383  # clipped rows may repeat
    assert repeated_tail_rows(rows) == 0


def test_ingest_offers_every_file_to_libraw_whatever_its_suffix(arw, tmp_path):
    shutil.copy(arw, tmp_path / "frame.kdc")  # not a suffix any list would hold for a Sony file
    (tmp_path / "notes.txt").write_text("lens: 55-210")
    (tmp_path / "bracket-01.json").write_text("{}")
    result = ingest_folder(tmp_path)
    assert result.brackets == []
    assert len(result.report) == 2
    assert "notes.txt" in result.report[0] and "LibRaw" in result.report[0]
    assert "frame.kdc" in result.report[1] and "not in a bracket" in result.report[1]


# -- the clip level, measured --------------------------------------------------------------------------------------
def test_a_pile_up_below_white_is_the_clip_level_and_scatter_above_it_counts_as_clipped(tmp_path):
    rng = np.random.default_rng(1)
    path = write_dng(tmp_path / "f.dng", sensor_dn(_scene(), 0.01, rng, clip_dn=13500, scatter_dn=256))
    frame = read_raw(path)
    assert np.all(frame.clip_level_tile_dn == 13500)
    assert read_ldr_frame(path)[:, 50:].min() == 1.0  # clipped in reconstruct's eyes (was 0.82 of white)


@pytest.mark.parametrize("make, black, clip, white", [("Canon", 2048, 13584, 15000), ("Nikon", 0, 3880, 4095),
                                                      ("Pentax", 64, 16300, 16383)])
def test_other_makes_levels_and_pile_ups(tmp_path, make, black, clip, white):
    """Canon-like high black and a white level above the pile-up, a 12-bit body, a pile-up just under white."""
    radiance = _scene() * (clip - black) / 1.0e4
    bayer = sensor_dn(radiance, 0.01, np.random.default_rng(9), black_dn=(black,) * 4, clip_dn=clip)
    frame = read_raw(write_dng(tmp_path / "f.dng", bayer, black_dn=(black,) * 4, white_dn=white, make=make))
    assert np.all(frame.clip_level_tile_dn == clip) and frame.metadata.white_level_dn == white
    assert frame.metadata.camera_model.startswith(make) and read_ldr_frame(frame.metadata.path)[:, 50:].min() == 1.0


def test_a_white_level_far_above_the_data_still_finds_the_pile_up(tmp_path):
    """12-bit data (black 256, clipping at 4095) in a DNG whose white level says 65535 (what LibRaw reports for a
    16-bit DNG without WhiteLevel): no sample reaches the top half of 256..65535, so the pile-up at the largest
    sample is the clip level; before, nothing counted as clipped and reconstruct saw no highlight."""
    radiance = _scene() * (4095 - 256) / 1.0e4
    bayer = sensor_dn(radiance, 0.01, np.random.default_rng(21), black_dn=(256,) * 4, clip_dn=4095)
    frame = read_raw(write_dng(tmp_path / "f.dng", bayer, black_dn=(256,) * 4, white_dn=65535))
    assert frame.metadata.white_level_dn == 65535 and np.all(frame.clip_level_tile_dn == 4095)
    assert read_ldr_frame(frame.metadata.path)[:, 50:].min() == 1.0
    frames = [read_raw(write_dng(tmp_path / f"{white}.dng", bayer, black_dn=(256,) * 4, white_dn=white))
              for white in (4095, 65535)]  # the same data declared both ways merges to the same units
    rates = [merge_bayer([frame], CAMERA, estimate_ratios=False).rate for frame in frames]
    np.testing.assert_allclose(rates[1], rates[0], rtol=1e-6)
    unclipped = sensor_dn(radiance / 4, 0.01, np.random.default_rng(22), black_dn=(256,) * 4, clip_dn=4095)
    assert unclipped.max() < 4095  # nothing clipped: no pile-up at its largest sample, the white level stays
    assert np.all(read_raw(write_dng(tmp_path / "g.dng", unclipped, black_dn=(256,) * 4, white_dn=65535)
                            ).clip_level_tile_dn == 65535)


def test_tifffile_complaints_about_formats_it_cannot_decode_are_not_printed(tmp_path):
    """An Olympus ORF starts "IIRO" (Panasonic RW2 "IIU"): tifffile logs "RAW format 0x4F52 not supported" on
    stderr while hdrcam reads the TIFF structure, although LibRaw decodes the file; nothing of it is printed
    (a fresh process: Python's last-resort handler is what prints it, and pytest replaces it)."""
    import subprocess
    import sys

    path = write_dng(tmp_path / "f.ORF", sensor_dn(_scene(), 0.01, np.random.default_rng(23)))
    data = bytearray(path.read_bytes())
    data[2:4] = b"RO"
    path.write_bytes(bytes(data))
    reading = subprocess.run([sys.executable, "-c", f"from hdrcam.io.raw import read_raw; read_raw({str(path)!r})"],
                             capture_output=True, text=True, check=True)
    assert reading.stderr == ""


def test_no_pile_up_means_the_metadata_white_level():
    rng = np.random.default_rng(2)
    ramp = np.linspace(512, 16300, 200_000) + rng.normal(0, 40, 200_000)  # a smooth bright area near white
    samples = np.clip(np.round(ramp), 0, 16383).astype(np.uint16)
    assert channel_clip_level(samples, 512, 16383) == 16383
    samples[:10] = 14000  # ten hot pixels at one value are no pile-up
    assert channel_clip_level(samples, 512, 16383) == 16383
    samples[:200] = 14000  # two hundred are
    assert channel_clip_level(samples, 512, 16383) == 14000


def test_merge_treats_samples_at_the_pile_up_as_clipped(tmp_path):
    """Long frame clipped at 13 500 DN under a white of 16 383: its clipped samples must not enter the merge
    (taken at face value they give 13 000 / 0.016 s, 0.41 of the truth)."""
    rng = np.random.default_rng(3)
    radiance = _scene()
    for name, exposure in (("short.dng", 0.002), ("long.dng", 0.016)):  # another make's labels: taken as written
        write_dng(tmp_path / name, sensor_dn(radiance, exposure, rng, clip_dn=13500), exposure_s=exposure)
    frames = [read_raw(tmp_path / "short.dng"), read_raw(tmp_path / "long.dng")]
    merge = merge_bayer(frames, CAMERA, estimate_ratios=False)
    assert np.all(merge.clip_level_tile_dn == 13500)
    to_dn_per_s = 1.0 / merge.to_relative
    bright = merge.rate[:, 56:] * to_dn_per_s
    assert abs(float(np.median(bright)) / 2.0e6 - 1) < 0.02
    assert merge.usable_frames[:, 56:].max() == 1  # only the short frame
    image = fuse([tmp_path], CAMERA)
    assert abs(float(np.median(image.merge.rate[:, 56:] * to_dn_per_s)) / 2.0e6 - 1) < 0.02


# -- layouts and quirks --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("cfa", ["RGGB", "BGGR", "GRBG", "GBRG"])
def test_cfa_layouts_and_per_channel_black_levels_are_read_as_written(tmp_path, cfa):
    bayer = sensor_dn(_scene(), 0.004, np.random.default_rng(4), black_dn=(500, 510, 520, 530))
    frame = read_raw(write_dng(tmp_path / "f.dng", bayer, cfa=cfa, black_dn=(500, 510, 520, 530)))
    assert frame.metadata.cfa_pattern == cfa and frame.metadata.black_level_dn == (500, 510, 520, 530)
    assert np.array_equal(frame.bayer_dn, bayer)


def test_x_trans_is_refused_clearly(tmp_path):
    bayer = sensor_dn(_scene(60, 96), 0.004, np.random.default_rng(5))
    with pytest.raises(InputError, match="X-Trans"):
        read_raw_metadata(write_dng(tmp_path / "xtrans.dng", bayer, cfa=XTRANS, make="Fujifilm", model="X-T3"))


def test_a_truncated_dng_is_refused(tmp_path):
    bayer = sensor_dn(_scene(), 0.004, np.random.default_rng(6))
    path = write_dng(tmp_path / "f.dng", bayer, truncate_to=9000)
    with pytest.raises(InputError, match="truncated"):
        read_raw(path)


@pytest.mark.parametrize("matrix", [np.zeros((3, 3)), None])
def test_a_zero_or_missing_colour_matrix_falls_back_to_camera_rgb_with_a_warning(tmp_path, matrix):
    rng = np.random.default_rng(7)
    for name, exposure in (("a.dng", 0.002), ("b.dng", 0.008)):
        write_dng(tmp_path / name, sensor_dn(_scene(), exposure, rng), exposure_s=exposure, colour_matrix=matrix,
                  make="Obscura", model="Prototype")
    assert read_raw_metadata(tmp_path / "a.dng").colour_matrix_source == NO_COLOUR_MATRIX
    with pytest.warns(UserWarning, match="camera RGB"):
        image = fuse([tmp_path], CAMERA)
    assert image.colour == "camera RGB" and np.isfinite(image.rgb).all()


def test_fuse_cli_on_a_zero_colour_matrix_exits_0_with_a_warning(tmp_path, capsys):
    rng = np.random.default_rng(8)
    for name, exposure in (("a.dng", 0.002), ("b.dng", 0.008)):
        write_dng(tmp_path / name, sensor_dn(_scene(), exposure, rng), exposure_s=exposure,
                  colour_matrix=np.zeros((3, 3)))
    with pytest.warns(UserWarning, match="camera RGB"):  # the CLI prints it as "hdrcam: warning: ..."
        assert main(["fuse", str(tmp_path), "--out", str(tmp_path / "hdr.exr")]) == 0
    assert "error" not in capsys.readouterr().err


def test_a_raw_too_large_for_the_memory_is_refused_before_its_pixels_are_decoded(tmp_path, monkeypatch):
    """The sizes come from the header: with 100 MB of memory left a 64 x 48 DNG passes, and with 10 kB it is
    refused naming the file and the numbers, before LibRaw unpacks anything."""
    import rawpy

    import hdrcam.limits as limits

    radiance = np.full((48, 64), 2000.0)
    path = write_dng(tmp_path / "small.dng", sensor_dn(radiance, 1.0, np.random.default_rng(0)))
    unpacked = []

    class Spy(rawpy.RawPy):
        def unpack(self):
            unpacked.append(self)
            return super().unpack()

    monkeypatch.setattr(rawpy, "RawPy", Spy)
    monkeypatch.setattr(limits, "available_memory_bytes", lambda: 100e6)
    assert read_raw(path).bayer_dn.shape == (48, 64) and len(unpacked) == 1
    monkeypatch.setattr(limits, "available_memory_bytes", lambda: 10e3)
    with pytest.raises(InputError, match=r"small\.dng.*64 x 48 px"):
        read_raw(path)
    assert len(unpacked) == 1


# -- a bracket's frames each carry their own levels ----------------------------------------------------------------
def test_each_frame_is_merged_above_its_own_black_level(tmp_path):
    """Canon-like bodies measure black from the masked border of every file, so two frames of one bracket can
    declare 2048 and 2051 DN: the long frame's 3 DN, read as signal, are ~10 % of a dim area's 32 DN."""
    rng = np.random.default_rng(11)
    radiance = np.full((64, 96), 2.0e3)  # DN per second above black: 4 DN in the short frame, 32 in the long one
    for name, exposure, black in (("short.dng", 0.002, 2048), ("long.dng", 0.016, 2051)):
        bayer = sensor_dn(radiance, exposure, rng, black_dn=(black,) * 4, clip_dn=15000)
        write_dng(tmp_path / name, bayer, black_dn=(black,) * 4, white_dn=15000, exposure_s=exposure)
    frames = [read_raw(tmp_path / "short.dng"), read_raw(tmp_path / "long.dng")]
    merge = merge_bayer(frames, CAMERA, estimate_ratios=False)
    assert abs(float(np.median(merge.rate / merge.to_relative)) / 2.0e3 - 1) < 0.02


def test_a_bracket_mixing_bit_depths_is_refused(tmp_path):
    """12-bit frames (a 12-bit setting or drive mode; LibRaw reports black 128 / white 4095 for a 12-bit Sony ARW)
    among 14-bit ones (black 512 / white 16383) would be merged on the wrong scale."""
    rng = np.random.default_rng(12)
    write_dng(tmp_path / "a14.dng", sensor_dn(_scene(), 0.002, rng), exposure_s=0.002)
    twelve_bit = sensor_dn(_scene() / 4, 0.016, rng, black_dn=(128,) * 4, clip_dn=4095)
    write_dng(tmp_path / "b12.dng", twelve_bit, black_dn=(128,) * 4, white_dn=4095, exposure_s=0.016)
    with pytest.raises(InputError, match="b12.dng: white level 4095 DN, 12 bits where the bracket.s others have 14"):
        read_bracket([tmp_path])


# -- DNG colour: the whole XYZ -> camera transform ------------------------------------------------------------------
def _with_tags(path, extra_tags, drop=()):
    """Rewrite a DNG written by write_dng with extra TIFF tags (tifffile's extratags tuples), less ``drop``."""
    import tifffile

    with tifffile.TiffFile(path) as tiff:
        page = tiff.pages[0]
        data = page.asarray()
        tags = [(tag.code, tag.dtype, tag.count, tag.value, True) for tag in page.tags.values()
                if (tag.code >= 33000 or tag.code in (271, 272)) and tag.code not in drop]
    tifffile.imwrite(path, data, photometric=tifffile.PHOTOMETRIC.CFA, compression=None, subfiletype=0,
                     extratags=tags + list(extra_tags), metadata=None)
    return path


def _srationals(values):
    return tuple(v for value in np.ravel(values) for v in (round(float(value) * 10000), 10000))


def test_a_dng_colour_matrix_includes_its_camera_calibration_and_analog_balance(tmp_path):
    """DNG: XYZ -> camera = AnalogBalance x CameraCalibration x ColorMatrix (phones' DNGs carry a per-unit
    CameraCalibration); a ColorMatrix alone is off by up to 20 % here."""
    from tests.io.realistic_dng import XYZ_TO_CAMERA

    calibration, balance = np.diag([1.08, 1.0, 0.93]), (1.1, 1.0, 0.9)
    path = write_dng(tmp_path / "f.dng", sensor_dn(_scene(), 0.004, np.random.default_rng(13)))
    _with_tags(path, [(50723, "2i", 9, _srationals(calibration), True),
                      (50727, "2I", 3, _srationals(balance), True)])
    meta = read_raw_metadata(path)
    assert np.allclose(meta.xyz_to_camera, np.diag(balance) @ calibration @ XYZ_TO_CAMERA, atol=1e-4)
    # a calibration signed for another profile is not applied (DNG 1.2: the signatures must match)
    _with_tags(path, [(50931, "s", 0, "unit 1234", True), (50932, "s", 0, "generic", True)])
    assert np.allclose(read_raw_metadata(path).xyz_to_camera, np.diag(balance) @ XYZ_TO_CAMERA, atol=1e-4)


def test_an_as_shot_white_given_as_xy_gives_the_neutral(tmp_path):
    """AsShotWhiteXY instead of AsShotNeutral: LibRaw reports no white balance; the neutral is the camera's
    response to that white."""
    from tests.io.realistic_dng import XYZ_TO_CAMERA

    path = write_dng(tmp_path / "f.dng", sensor_dn(_scene(), 0.004, np.random.default_rng(14)))
    _with_tags(path, [(50729, "2I", 2, (3127, 10000, 3290, 10000), True)], drop={50728})  # AsShotNeutral out
    xyz = np.array([0.3127 / 0.3290, 1.0, (1 - 0.3127 - 0.3290) / 0.3290])
    neutral = XYZ_TO_CAMERA @ xyz
    assert np.allclose(read_raw_metadata(path).as_shot_neutral, neutral / neutral.max(), atol=1e-3)


def test_an_as_shot_white_given_as_xy_counts_with_libraws_matrix_for_the_model_too(tmp_path):
    """AsShotWhiteXY in a DNG without ColorMatrix1, of a model LibRaw has a table for: the white was dropped for
    daylight (and fuse would have said the file records none). The neutral is that white through LibRaw's matrix."""
    path = write_dng(tmp_path / "f.dng", sensor_dn(_scene(), 0.004, np.random.default_rng(17)), colour_matrix=None,
                     make="SONY", model="ILCE-7RM3")
    _with_tags(path, [(50729, "2I", 2, (3457, 10000, 3585, 10000), True)], drop={50728})  # about 5000 K
    meta = read_raw_metadata(path)
    assert meta.colour_matrix_source == "LibRaw" and meta.white_balance_source == "as shot"
    xyz = np.array([0.3457 / 0.3585, 1.0, (1 - 0.3457 - 0.3585) / 0.3585])
    neutral = meta.xyz_to_camera @ xyz
    assert np.allclose(meta.as_shot_neutral, neutral / neutral.max(), atol=1e-6)


def test_a_dng_without_an_as_shot_white_is_balanced_for_daylight_and_says_so(tmp_path):
    """A colour matrix but neither AsShotNeutral nor AsShotWhiteXY: LibRaw reports camera_whitebalance
    [0, 1, 0, 0], and ones for the neutral left a D65-grey ramp at R/G 0.15, B/G 0.38 (a strong green cast) without
    a word. D65 through the matrix, LibRaw's own daylight balance, keeps it grey, and fuse warns once."""
    import warnings

    import rawpy

    from tests.io.realistic_dng import XYZ_TO_CAMERA

    neutral = XYZ_TO_CAMERA @ np.array([0.3127 / 0.3290, 1.0, (1 - 0.3127 - 0.3290) / 0.3290])
    neutral /= neutral.max()
    height, width = 64, 96
    ramp = 2.0 ** (8 + 6 * np.mgrid[0:height, 0:width][1] / (width - 1))  # DN per second at the brightest site
    radiance = np.tile([[neutral[0], neutral[1]], [neutral[1], neutral[2]]], (height // 2, width // 2)) * ramp
    rng = np.random.default_rng(4)
    for exposure in (0.01, 0.04, 0.16):
        path = write_dng(tmp_path / f"f{exposure}.dng", sensor_dn(radiance, exposure, rng), exposure_s=exposure)
        _with_tags(path, [], drop={50728})  # AsShotNeutral out
    meta = read_raw_metadata(path)
    with rawpy.imread(str(path)) as raw:
        assert raw.camera_whitebalance[0] == 0
        daylight = 1.0 / np.array(raw.daylight_whitebalance[:3])
    assert np.allclose(meta.as_shot_neutral, daylight / daylight.max(), atol=1e-3)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        image = fuse([tmp_path], CAMERA)
    said = [str(w.message) for w in caught if "assumed to be daylight" in str(w.message)]
    assert len(said) == 1, said
    grey = image.rgb[8:-8, 8:-8].reshape(-1, 3)
    assert abs(np.median(grey[:, 0] / grey[:, 1]) - 1) < 0.03 and abs(np.median(grey[:, 2] / grey[:, 1]) - 1) < 0.03


@pytest.mark.parametrize("masked", [False, True])
def test_a_dngs_black_level_tags_are_read_as_written(tmp_path, masked):
    """Fractional BlackLevel values per position (a 2 x 2 BlackLevelRepeatDim) and BlackLevelDeltaV on each row
    (an Adobe-converted Canon 400D: BlackLevel 0, 256 in DeltaV) give the black level of each position as written
    (DNG spec 1.4, chapter 6). LibRaw rounds fractional levels to whole DN and, with MaskedAreas, replaces the tags
    by its measurement of those areas (here dark-current-free masked pixels at 250 DN)."""
    height, width = 64, 96
    full = np.full((height + 4, width + 4), 250, np.uint16)
    signal = sensor_dn(_scene(height, width) / 50, 0.004, np.random.default_rng(15), black_dn=(0, 0, 0, 0))
    fractional = (512.25, 512.5, 512.5, 512.75)
    full[4:, 4:] = signal + np.tile(np.reshape(fractional, (2, 2)), (height // 2, width // 2)).round().astype(np.uint16)
    path = write_dng(tmp_path / "f.dng", full)
    tags = [(50829, "I", 4, (4, 4, height + 4, width + 4), True),  # ActiveArea: top, left, bottom, right
            (50714, "2I", 4, _srationals(fractional), True)]  # BlackLevel, RATIONAL
    if masked:
        tags += [(50830, "I", 4, (4, 0, height + 4, 2), True)]  # MaskedAreas: the two columns on the left
    _with_tags(path, tags, drop={50714})
    assert read_raw_metadata(path).black_level_dn == fractional
    full[4:, 4:] = signal + 256
    path = write_dng(tmp_path / "canon.dng", full)
    _with_tags(path, [tags[0], (50714, "H", 1, (0,), True), (50713, "H", 2, (1, 1), True),
                      (50716, "2i", height, (25600, 100) * height, True)] + tags[2:], drop={50713, 50714})
    assert read_raw_metadata(path).black_level_dn == (256.0,) * 4


def test_a_dng_black_level_of_short_values_is_read_by_its_type_and_a_square_count_as_its_repeat(tmp_path):
    """BlackLevel as four SHORT values and no BlackLevelRepeatDim: taken for two rationals, 512 / 512 gave a black
    of 1.0. The values are the tag's type's; four of them without a repeat are a 2 x 2 one, as dcraw takes them."""
    height, width = 64, 96
    levels = (510, 512, 513, 515)
    signal = sensor_dn(_scene(height, width) / 50, 0.004, np.random.default_rng(16), black_dn=(0, 0, 0, 0))
    path = write_dng(tmp_path / "f.dng", signal + np.tile(np.reshape(levels, (2, 2)), (height // 2, width // 2)
                                                          ).astype(np.uint16))
    _with_tags(path, [(50714, "H", 4, levels, True)], drop={50713, 50714})
    assert read_raw_metadata(path).black_level_dn == tuple(float(level) for level in levels)


def _gain_map_opcode_list(height: int, width: int) -> bytes:
    """An OpcodeList (big-endian) holding one GainMap (ID 9) of 2 x 2 gains over the whole image."""
    parameters = struct.pack(">IIIIIIII", 0, 0, height, width, 0, 1, 1, 1) + struct.pack(">II", 2, 2)
    parameters += struct.pack(">dddd", 1.0, 1.0, 0.0, 0.0) + struct.pack(">I", 1) + struct.pack(">4f", 2, 1, 1, 2)
    return struct.pack(">I", 1) + struct.pack(">IIII", 9, 0x01030000, 0, len(parameters)) + parameters


def test_a_dngs_lens_shading_gain_map_left_out_is_said(tmp_path):
    """Phones and drones write lens shading as an OpcodeList2 GainMap, which LibRaw (rawpy's build) does not
    apply: the metadata and `inspect` name it, and reading the frame for reconstruction warns once."""
    path = write_dng(tmp_path / "phone.dng", sensor_dn(_scene(), 0.004, np.random.default_rng(24)))
    opcodes = _gain_map_opcode_list(64, 96)
    _with_tags(path, [(51009, "B", len(opcodes), opcodes, True)])
    assert read_raw_metadata(path).shading_not_applied == ("GainMap (OpcodeList2)",)
    assert raw_summary(path)["shading_not_applied"] == ["GainMap (OpcodeList2)"]
    with pytest.warns(UserWarning, match=r"phone\.dng: GainMap \(OpcodeList2\) not applied"):
        read_ldr_frame(path)
    plain = write_dng(tmp_path / "plain.dng", sensor_dn(_scene(), 0.004, np.random.default_rng(24)))
    assert read_raw_metadata(plain).shading_not_applied == ()


def test_a_monochrome_dng_is_refused_as_monochrome(tmp_path):
    """A 1-sample LinearRaw DNG (a Leica M Monochrom's kind): LibRaw reports one colour and a 1 x 1 pattern
    with a stale colour description ("GMCY"); the refusal names what the sensor is."""
    import tifffile

    path = tmp_path / "mono.dng"
    bayer = sensor_dn(_scene(), 0.004, np.random.default_rng(25))
    tifffile.imwrite(path, bayer, photometric="minisblack", compression=None, subfiletype=0, metadata=None,
                     extratags=[(50706, "B", 4, (1, 4, 0, 0), True), (50717, "H", 1, (16383,), True)])
    with tifffile.TiffFile(path) as tiff:
        offset = tiff.pages[0].tags[262].valueoffset
    data = bytearray(path.read_bytes())
    data[offset:offset + 2] = struct.pack("<H", 34892)  # PhotometricInterpretation: LinearRaw
    path.write_bytes(bytes(data))
    with pytest.raises(InputError, match="monochrome sensor"):
        read_raw(path)


def test_ingest_does_not_group_frames_of_two_bit_depths(tmp_path):
    """The same bit-depth rule as fuse's: a 12-bit frame among 14-bit ones is not put in their bracket."""
    rng = np.random.default_rng(26)
    write_dng(tmp_path / "a.dng", sensor_dn(_scene(), 0.002, rng), exposure_s=0.002)
    twelve_bit = sensor_dn(_scene() / 4, 0.008, rng, black_dn=(128,) * 4, clip_dn=4095)
    write_dng(tmp_path / "b.dng", twelve_bit, black_dn=(128,) * 4, white_dn=4095, exposure_s=0.008)
    write_dng(tmp_path / "c.dng", sensor_dn(_scene(), 0.016, rng), exposure_s=0.016)
    assert main(["ingest", str(tmp_path)]) == 0
    for manifest in tmp_path.glob("bracket-*.json"):
        assert len({frame.metadata.white_level_dn for frame in read_bracket([manifest])}) == 1


def test_shading_opcodes_are_named_once_and_only_for_the_raw_image(tmp_path):
    """A GainMap per Bayer plane (as phones write four) is one name; an opcode on a preview IFD is not the raw
    image's."""
    import tifffile

    path = write_dng(tmp_path / "f.dng", sensor_dn(_scene(), 0.004, np.random.default_rng(27)))
    one = _gain_map_opcode_list(64, 96)
    four = struct.pack(">I", 4) + one[4:] * 4
    _with_tags(path, [(51009, "B", len(four), four, True)])
    assert read_raw_metadata(path).shading_not_applied == ("GainMap (OpcodeList2)",)
    vignette = struct.pack(">I", 1) + struct.pack(">IIII", 3, 0x01030000, 0, 56) + bytes(56)
    tifffile.imwrite(path, np.zeros((8, 12, 3), np.uint8), append=True, subfiletype=1, photometric="rgb",
                     extratags=[(51022, "B", len(vignette), vignette, True)], metadata=None)
    assert read_raw_metadata(path).shading_not_applied == ("GainMap (OpcodeList2)",)


def test_only_the_raw_images_opcodes_are_named_not_a_masks_or_an_enhanced_images(tmp_path):
    """The raw image is a full-resolution image page (hdrcam.io.tiff_image.is_full_resolution_image), which a DNG's
    transparency mask (NewSubfileType 4) and enhanced image (16) are not, though neither is a reduced copy."""
    import tifffile

    path = write_dng(tmp_path / "f.dng", sensor_dn(_scene(), 0.004, np.random.default_rng(28)))
    vignette = struct.pack(">I", 1) + struct.pack(">IIII", 3, 0x01030000, 0, 56) + bytes(56)
    tifffile.imwrite(path, np.zeros((64, 96), bool), append=True, subfiletype=4, metadata=None,
                     extratags=[(51022, "B", len(vignette), vignette, True)])
    tifffile.imwrite(path, np.zeros((64, 96, 3), np.uint16), append=True, subfiletype=16, photometric="rgb",
                     extratags=[(51022, "B", len(vignette), vignette, True)], metadata=None)
    assert read_raw_metadata(path).shading_not_applied == ()


def test_the_noise_peak_of_a_flat_unclipped_area_is_not_a_clip_level_and_a_dozen_clipped_samples_are():
    rng = np.random.default_rng(0)
    ramp = rng.integers(512, 15700, 60_000)  # a bright gradient, nothing clipped
    wall = np.round(rng.normal(12_000, 60, 20_000))  # a flat wall at 0.75 of white with shot noise
    samples = np.concatenate([ramp, wall]).astype(np.uint16)
    assert channel_clip_level(samples, 512, 16383) == 16383  # its peak was taken for the clip: frame x 1.67
    scene = rng.integers(512, 13_500, 8_000)  # a night scene's sparse bright samples, clipping at 13 500
    lights = np.concatenate([scene, np.full(12, 13_500)]).astype(np.uint16)  # 3 lights of 4 x 4 px
    assert channel_clip_level(lights, 512, 16383) == 13_500  # 16 samples were needed: such lights read 0.82


def test_a_pile_up_spread_over_a_few_dn_is_still_found():
    rng = np.random.default_rng(1)
    scene = rng.integers(512, 13_495, 200_000)
    spread = 13_495 + rng.integers(0, 6, 5_000)  # clipped, then offset per column by 0-5 DN
    level = channel_clip_level(np.concatenate([scene, spread]).astype(np.uint16), 512, 16383)
    assert 13_495 <= level <= 13_500  # its nearest neighbours are the pile itself: white was taken instead


def test_a_file_without_a_capture_time_has_none_and_a_model_that_repeats_the_make_is_named_once(tmp_path):
    """LibRaw reports 0 for a file without DateTime, which rawpy turns into 1970-01-01: ingest then took it for a
    time and grouped brackets shot hours apart as one. Canon's Model tag repeats its Make: "Canon Canon EOS 5D
    Mark III" was the camera's name in manifests and messages."""
    path = write_dng(tmp_path / "f.dng", sensor_dn(_scene(), 0.004, np.random.default_rng(18)), datetime=None,
                     make="Canon", model="Canon EOS 5D Mark III")
    meta = read_raw_metadata(path)
    assert meta.timestamp is None
    assert meta.camera_model == "Canon EOS 5D Mark III"
    path = write_dng(tmp_path / "g.dng", sensor_dn(_scene(), 0.004, np.random.default_rng(18)), make="SONY",
                     model="ILCE-7RM3")
    assert read_raw_metadata(path).camera_model == "SONY ILCE-7RM3"
    assert read_raw_metadata(path).timestamp == dt.datetime(2026, 11, 24, 12, 0, 0)


def test_a_small_lamp_on_a_body_clipping_below_its_white_level_is_clipped_in_every_position(tmp_path):
    """A 3 x 3 px lamp on a body that clips at 15 000 DN under a white level of 16 383 clips two to four samples
    of each CFA position, fewer than a pile-up needs: every position kept 16 383, the lamp read 0.91 of white and
    reconstruct said "no clipped pixels". The four positions' samples together show the sensor's pile-up."""
    from hdrcam.io.ldr_frame import raw_relative_rgb
    from hdrcam.io.raw import read_raw

    radiance = np.tile(2000.0 + 30.0 * np.arange(160), (120, 1))  # DN per second above black
    radiance[40:43, 60:63] = 1e6
    for wall, hot in ((False, False), (True, False), (True, True)):  # a brightly lit, unclipped wall holds more
        if wall:  # samples in the top part than the lamp: 9000 DN, the shared histogram's mode, where its argmax was
            radiance[5:35, 5:75] = 90000.0  # looked for; a hot pixel above the pile moved a window from the top
        bayer = sensor_dn(radiance, 0.1, np.random.default_rng(19), clip_dn=15000)
        if hot:
            bayer[100, 100] = 16383
        path = write_dng(tmp_path / "lamp.dng", bayer)
        frame = read_raw(path)
        assert frame.clip_level_tile_dn.tolist() == [[15000, 15000], [15000, 15000]]
        assert np.all(raw_relative_rgb(frame)[41, 61] == 1.0)
