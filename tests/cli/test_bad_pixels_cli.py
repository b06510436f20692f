"""``hdrcam bad-pixels`` writes a dcraw list from RAW frames; ``hdrcam reconstruct --bad-pixels`` repairs them."""

from __future__ import annotations

import json

import numpy as np

from hdrcam.cli import main
from hdrcam.io.bad_pixels import read_bad_pixels
from hdrcam.io.exr import read_exr
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
