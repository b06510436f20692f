"""Inputs and arguments found by an audit of every command's bad-input handling: each ends in one line and exit 1,
never an internal error (exit 3), and leaves nothing behind."""

from __future__ import annotations

import os
import stat
import struct
import zlib

import cv2
import numpy as np
import pytest

from tests.faults.helpers import assert_failed_with_one_line, run


def _png_declaring(path, width: int, height: int) -> None:
    """A small 16-bit RGB PNG whose IHDR (with a valid CRC) declares ``width`` x ``height`` pixels."""
    cv2.imwrite(str(path), np.full((8, 8, 3), 30000, np.uint16))
    data = bytearray(path.read_bytes())
    data[16:24] = struct.pack(">II", width, height)  # IHDR: length, type, width, height, ...
    data[29:33] = struct.pack(">I", zlib.crc32(bytes(data[12:29])) & 0xFFFFFFFF)
    path.write_bytes(bytes(data))


@pytest.mark.parametrize("argv", [
    lambda frame, out: ["destreak", frame, "--out", out],
    lambda frame, out: ["simulate", frame, "--psf", "dirac", "--out", out / "frame.exr"],
], ids=["destreak", "simulate"])
def test_a_png_declaring_more_pixels_than_opencv_decodes_is_one_line(argv, tmp_path, capsys):
    """OpenCV raises its own error (not None) for a header beyond 2^30 pixels: it was an internal error, exit 3."""
    frame = tmp_path / "huge.png"
    _png_declaring(frame, 100_000, 100_000)
    out = tmp_path / "out"
    assert_failed_with_one_line(run(argv(frame, out), capsys), 1, str(frame))
    assert not out.exists()


def test_a_bracket_of_absurdly_many_stops_is_refused_in_one_line(tmp_path, capsys):
    """The longest exposure of --stops 100000 overflowed a float while the refusal was being worded (exit 3)."""
    out = tmp_path / "bracket"
    line = assert_failed_with_one_line(run(["capture", "bracket", "--camera", "sim", "--profile", "simulated",
                                            "--psf", "dirac", "--size", "64x48", "--stops", "100000",
                                            "--out", out], capsys), 1, "--stops")
    assert "30 s" in line
    assert not out.exists()


@pytest.mark.parametrize("through_a_link", [False, True], ids=["itself", "through-a-link"])
def test_overwrite_never_puts_a_file_in_place_of_a_pipe_or_device(through_a_link, tmp_path, capsys):
    """A FIFO stands for /dev/null: --overwrite replaced it (a root user's /dev/null) with the EXR."""
    fifo = tmp_path / "fifo.exr"
    os.mkfifo(fifo)
    out = tmp_path / "link.exr" if through_a_link else fifo
    if through_a_link:
        out.symlink_to(fifo)
    assert_failed_with_one_line(run(["simulate", "night", "--psf", "dirac", "--size", "32", "32", "--out", out,
                                     "--overwrite"], capsys), 1, str(out), "not a regular file")
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)
    assert os.path.islink(out) == through_a_link
    assert sorted(path.name for path in tmp_path.iterdir()) == sorted({"fifo.exr", out.name})


@pytest.mark.parametrize("outputs", [["--out", "frame.png"], ["--out", "frame.exr", "--truth", "truth.tif"],
                                     ["--out", "frame"]], ids=["png", "truth-tif", "no-suffix"])
def test_simulate_names_its_outputs_as_exr_files(outputs, tmp_path, capsys):
    """simulate wrote OpenEXR bytes under any name (frame.png: an EXR that image viewers cannot open); fuse
    already asks for NAME.exr."""
    argv = ["simulate", "night", "--psf", "dirac", "--size", "32", "32",
            *(tmp_path / word if index % 2 else word for index, word in enumerate(outputs))]
    assert_failed_with_one_line(run(argv, capsys), 1, str(tmp_path / outputs[-1]), "NAME.exr")
    assert list(tmp_path.iterdir()) == []


def test_a_folder_given_as_the_scene_is_named_as_a_folder(tmp_path, capsys):
    """simulate said 'no such file' of a folder that exists (reconstruct and destreak already say 'is a folder')."""
    scene = tmp_path / "scene.exr"
    scene.mkdir()
    assert_failed_with_one_line(run(["simulate", scene, "--psf", "dirac", "--out", tmp_path / "frame.exr"], capsys),
                                1, str(scene), "a folder")
    assert list(tmp_path.iterdir()) == [scene]


@pytest.mark.parametrize("argv, expected", [
    (lambda d, frame, out: ["psf", "--profile", "simulated", "--psf-size", "15", "--doe", d, "--out", out],
     "{d}: a folder, not an image file"),
    (lambda d, frame, out: ["fabricate", d, "--out", out], "{d}: a folder, not an image file"),
    (lambda d, frame, out: ["capture", "bracket", "--profile", "simulated", "--size", "64x48", "--psf", d, "--out",
                            out], "{d}: a folder, not an image file"),
    (lambda d, frame, out: ["simulate", "night", "--size", "32", "32", "--psf", d, "--out", out / "f.exr"],
     "--psf {d}: a folder, not a PSF (EXR file)"),
    (lambda d, frame, out: ["simulate", "night", "--size", "32", "32", "--checkpoint", d, "--out", out / "f.exr"],
     "{d}: a folder, not a checkpoint file"),
    (lambda d, frame, out: ["reconstruct", frame, "--psf", d, "--out", out],
     "{d}: a folder, not an image file"),
    (lambda d, frame, out: ["reconstruct", frame, "--checkpoint", d, "--out", out],
     "{d}: a folder, not a checkpoint file"),
    (lambda d, frame, out: ["reconstruct", frame, "--partner", d, "--out", out],
     "{d}: a folder, not a checkpoint file"),
    (lambda d, frame, out: ["destreak", frame, "--method", "network", "--checkpoint", d, "--out", out],
     "{d}: a folder, not a checkpoint file"),
    (lambda d, frame, out: ["evaluate", "--count", "1", "--size", "64", "--psf", d, "--out", out],
     "{d}: a folder, not an image file"),
    (lambda d, frame, out: ["design", "--steps", "1", "--psf", d, "--out", out],
     "--psf {d}: a folder, not one of dirac, star8, dual-peak, windshield or a PSF (EXR file)"),
    (lambda d, frame, out: ["design", "--steps", "1", "--init", d, "--out", out],
     "--init {d}: a folder, not a checkpoint file"),
    (lambda d, frame, out: ["finetune", "--steps", "1", "--psf", d, "--out", out],
     "--psf {d}: a folder, not a PSF (EXR file)"),
], ids=["psf-doe", "fabricate", "capture-psf", "simulate-psf", "simulate-checkpoint", "reconstruct-psf",
        "reconstruct-checkpoint", "reconstruct-partner", "destreak-checkpoint", "evaluate-psf", "design-psf",
        "design-init", "finetune-psf"])
def test_a_folder_given_as_an_input_file_is_named_as_a_folder(argv, expected, tmp_path, capsys):
    """Each said 'no such file' or 'does not exist' of a folder that exists."""
    from hdrcam.io.exr import write_exr

    folder, frame, out = tmp_path / "given", tmp_path / "frame.exr", tmp_path / "out"
    folder.mkdir()
    write_exr(frame, np.full((32, 32, 3), 0.2, np.float32), channel_names=("R", "G", "B"))
    line = assert_failed_with_one_line(run(argv(folder, frame, out), capsys), 1)
    assert line.endswith(": error: " + expected.format(d=folder)), line
    assert sorted(tmp_path.iterdir()) == [frame, folder] and list(folder.iterdir()) == []


@pytest.mark.parametrize("command", ["reconstruct", "destreak"])
def test_an_all_white_frame_among_good_ones_is_refused_before_any_output(command, tmp_path, capsys):
    """An all-saturated frame is bad input (it records no scene and no streak): one line naming it, exit 1, and
    no output for any frame of the run - every input is checked before any work."""
    from hdrcam.io.exr import write_exr

    good, white = tmp_path / "good.exr", tmp_path / "white.exr"
    frame = np.full((64, 64, 3), 0.2, np.float32)
    frame[30:34, 30:34] = 1.0
    write_exr(good, frame, channel_names=("R", "G", "B"))
    write_exr(white, np.ones((64, 64, 3), np.float32), channel_names=("R", "G", "B"))
    out = tmp_path / "out"
    assert_failed_with_one_line(run([command, good, white, "--out", out], capsys), 1, str(white))
    assert not out.exists()


def test_a_png_declaring_more_than_memory_holds_is_refused_before_decoding(tmp_path, monkeypatch):
    """Under OpenCV's own 2^30-pixel limit a PNG's header is all it checks: 30000 x 30000 px (5.4 GB decoded,
    more with the float copy) went on to decode. Sized from IHDR first, as EXR, TIFF and Radiance files are."""
    from hdrcam import limits
    from hdrcam.errors import TooLargeError
    from hdrcam.io.ldr_frame import read_ldr_frame

    frame = tmp_path / "big.png"
    _png_declaring(frame, 30_000, 30_000)
    monkeypatch.setattr(limits, "available_memory_bytes", lambda: 1e9)
    monkeypatch.setattr(cv2, "imread", lambda *arguments: pytest.fail("decoded before its size was checked"))
    with pytest.raises(TooLargeError, match="30000 x 30000 px"):
        read_ldr_frame(frame)
