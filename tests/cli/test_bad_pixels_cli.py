"""``hdrcam bad-pixels`` writes a dcraw list from RAW frames; ``hdrcam reconstruct --bad-pixels`` repairs them."""

from __future__ import annotations

import json

import numpy as np
import tifffile

from hdrcam.cli import main
from hdrcam.io.bad_pixels import read_bad_pixels
from hdrcam.io.exr import read_exr
from tests.io.realistic_dng import write_dng
from tests.io.test_bad_pixels import DEAD, HOT, _frames_with_defects


def test_bad_pixels_writes_the_list_and_keeps_an_existing_one(tmp_path, capsys):
    frames = tmp_path / "frames"
    _frames_with_defects(frames, 3)
    listed = tmp_path / "bad.txt"
    assert main(["bad-pixels", str(frames), "--out", str(listed)]) == 0
    assert capsys.readouterr().out.strip() == f"{listed}: 2 bad pixels of 96 x 64 in 3 frames"
    assert np.argwhere(read_bad_pixels(listed).mask((64, 96))).tolist() == sorted([list(DEAD), list(HOT)])
    before = listed.read_bytes()
    assert main(["bad-pixels", str(frames), "--out", str(listed)]) == 1
    assert "already exists" in capsys.readouterr().err and listed.read_bytes() == before
    assert main(["bad-pixels", str(frames / "f0.dng"), "--out", str(tmp_path / "one.txt")]) == 1
    assert "at least 2 frames" in capsys.readouterr().err and not (tmp_path / "one.txt").exists()


def test_reconstruct_repairs_the_listed_pixels_and_refuses_a_broken_list(tmp_path, capsys):
    frame = _frames_with_defects(tmp_path / "frames", 3)[2]
    listed = tmp_path / "bad.txt"
    assert main(["bad-pixels", str(tmp_path / "frames"), "--out", str(listed)]) == 0
    capsys.readouterr()
    assert main(["reconstruct", str(frame), "--bad-pixels", str(listed), "--out", str(tmp_path / "out")]) == 0
    assert json.loads(capsys.readouterr().out)["bad_pixels_repaired"] == 2
    image = read_exr(tmp_path / "out" / "f2.exr")
    assert image.attributes["bad_pixels_repaired"] == 2
    hdr = image.rgb()
    assert hdr[HOT[0] - 1:HOT[0] + 2, HOT[1] - 1:HOT[1] + 2].max() < 0.2  # the flat field's ~0.12 (without the
    # list the hot pixel stays at white and its demosaiced neighbours read 0.34)

    (tmp_path / "broken.txt").write_text("12 7 0\nnot a pixel\n")
    assert main(["reconstruct", str(frame), "--bad-pixels", str(tmp_path / "broken.txt"), "--out",
                 str(tmp_path / "out2")]) == 1
    error = capsys.readouterr().err.strip()
    assert error.count("\n") == 0 and "broken.txt, line 2" in error and not (tmp_path / "out2").exists()


def test_fuse_repairs_the_listed_hot_pixels_of_a_bracket(tmp_path, capsys):
    """A simulated bracket of a flat field with hot pixels (0.2-4 full wells a second of dark charge), fused
    without darks: the hot pixels read high in the merge; with the list found in the bracket's darks they read
    as their neighbours (the flat field's own level)."""
    import hdrcam
    from hdrcam.capture.simulated import SensorDefects

    size, fraction, seed = (192, 128), 1.5e-3, 7
    hdrcam.capture_bracket(tmp_path / "b", camera="sim", profile="simulated", scene="flat:0.1", size_px=size,
                           shortest_s=1 / 30, stops=3, ev_step=2.0, darks=True, seed=seed, hot_pixel_fraction=fraction)
    listed = tmp_path / "bad.txt"
    assert main(["bad-pixels", str(tmp_path / "b" / "darks"), "--out", str(listed)]) == 0
    truth = SensorDefects.draw(size[1], size[0], fraction, seed)
    hot = (truth.hot_pixel_rows, truth.hot_pixel_columns)
    plain = hdrcam.fuse([tmp_path / "b"], profile="simulated").merge.rate
    repaired = hdrcam.fuse([tmp_path / "b"], profile="simulated", bad_pixels=listed)
    position_level = np.array([[np.median(plain[row::2, column::2]) for column in (0, 1)] for row in (0, 1)])
    level = position_level[hot[0] % 2, hot[1] % 2]  # each CFA colour's own level of the flat field (camera RGB)
    assert repaired.bad_pixels_repaired == len(hot[0]) == 37
    assert np.median(plain[hot] / level) > 1.2  # dark charge read as light (0.2-4 full wells a second)
    assert np.abs(repaired.merge.rate[hot] / level - 1.0).max() < 0.1  # the flat field's level, to its noise
    capsys.readouterr()
    assert main(["fuse", str(tmp_path / "b"), "--bad-pixels", str(listed), "--out", str(tmp_path / "hdr.exr"),
                 "--profile", "simulated"]) == 0
    assert "37 listed bad pixels repaired" in capsys.readouterr().out
    assert read_exr(tmp_path / "hdr.exr").attributes["bad_pixels_repaired"] == 37


def _refused(argv: list[str], out, capsys) -> str:
    """The one error line of a bad-pixels run that must exit 1 and write nothing."""
    from tests.faults.helpers import assert_failed_with_one_line, run

    error = assert_failed_with_one_line(run(argv, capsys))
    assert not out.exists()
    return error


def test_a_frame_counted_twice_is_refused(tmp_path, capsys):
    """The same file twice, a byte-identical copy or a link to a frame in a folder counted as one more frame, so a
    one-frame transient (a cosmic ray in one dark) was confirmed 'in every frame' and listed as a defect."""
    import os
    import shutil

    frames = _frames_with_defects(tmp_path / "frames", 3)
    out = tmp_path / "bad.txt"
    assert _refused(["bad-pixels", frames[0], frames[1], frames[0], "--out", out], out, capsys) == \
        f"hdrcam bad-pixels: error: {frames[0]}: given twice; give each frame once"
    copy = shutil.copyfile(frames[1], tmp_path / "frames" / "f1 (1).dng")
    assert _refused(["bad-pixels", tmp_path / "frames", "--out", out], out, capsys) == \
        f"hdrcam bad-pixels: error: {copy}: a copy of f1.dng (identical sha256); remove it from the frames"
    copy.unlink()
    os.symlink("f0.dng", tmp_path / "frames" / "link-to-f0.dng")
    assert _refused(["bad-pixels", tmp_path / "frames", "--out", out], out, capsys) == \
        (f"hdrcam bad-pixels: error: {tmp_path / 'frames' / 'link-to-f0.dng'}: the same file as f0.dng (one links to "
         "the other); give each frame once")


def test_a_folders_files_that_are_not_raw_are_skipped_with_a_warning_as_fuse_skips_them(tmp_path, capsys):
    """A JPEG beside each RAW (as cameras shoot RAW + JPEG) or a README made the whole folder refused."""
    import warnings

    frames = _frames_with_defects(tmp_path / "frames", 3)
    (tmp_path / "frames" / "f0.JPG").write_bytes(b"\xff\xd8\xff\xe0" + bytes(200))
    (tmp_path / "frames" / "README.txt").write_text("darks, lens capped\n")
    listed = tmp_path / "bad.txt"
    with warnings.catch_warnings(record=True) as warned:
        warnings.simplefilter("always")
        assert main(["bad-pixels", str(tmp_path / "frames"), "--out", str(listed)]) == 0
    assert capsys.readouterr().out.strip() == f"{listed}: 2 bad pixels of 96 x 64 in 3 frames"
    skipped = sorted(str(warning.message).split(":")[0] for warning in warned)
    assert skipped == [f"skipped {tmp_path / 'frames' / name}" for name in ("README.txt", "f0.JPG")]
    assert all("LibRaw does not open it as RAW" in str(warning.message) for warning in warned)
    out = tmp_path / "named.txt"  # a file named on the command line must be RAW
    error = _refused(["bad-pixels", *frames, tmp_path / "frames" / "f0.JPG", "--out", out], out, capsys)
    named = tmp_path / "frames" / "f0.JPG"
    assert error.startswith(f"hdrcam bad-pixels: error: {named}: LibRaw does not open it as RAW")


def test_frames_of_another_camera_model_are_refused(tmp_path, capsys):
    frames = _frames_with_defects(tmp_path / "frames", 2)
    other = write_dng(tmp_path / "frames" / "other.dng", np.asarray(tifffile.imread(frames[1])), model="Testbody 2")
    out = tmp_path / "bad.txt"
    assert _refused(["bad-pixels", frames[0], other, "--out", out], out, capsys) == \
        (f"hdrcam bad-pixels: error: {other}: camera model Acme Testbody 2 differs from f0.dng's Acme Testbody 1; bad "
         "pixels are found in frames of one camera")
