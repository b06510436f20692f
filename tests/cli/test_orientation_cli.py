"""A portrait-flagged RAW through inspect, fuse and reconstruct: the EXR keeps the sensor's orientation and says
the EXIF Orientation code in its ``orientation`` attribute; the PNG previews are turned upright."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from hdrcam.cli import main
from hdrcam.io.exr import read_exr
from tests.io.realistic_dng import sensor_dn, write_dng

HEIGHT, WIDTH = 64, 96  # the sensor's, landscape


def _bracket(folder, orientation: int | None):
    """Two frames of a scene whose right half clips in the long one."""
    folder.mkdir()
    radiance = np.full((HEIGHT, WIDTH), 2.0e5)
    radiance[:, WIDTH // 2:] = 2.0e6
    rng = np.random.default_rng(41)
    for name, exposure in (("a.dng", 0.002), ("b.dng", 0.008)):
        write_dng(folder / name, sensor_dn(radiance, exposure, rng), exposure_s=exposure, orientation=orientation)
    return folder


def _png(path) -> np.ndarray:
    return cv2.cvtColor(cv2.imread(str(path)), cv2.COLOR_BGR2RGB)


def test_inspect_says_the_orientation(tmp_path, capsys):
    folder = _bracket(tmp_path / "portrait", 6)
    upright = write_dng(tmp_path / "upright.dng", sensor_dn(np.full((HEIGHT, WIDTH), 2.0e5), 0.002,
                                                            np.random.default_rng(42)), orientation=1)
    assert main(["inspect", str(folder / "a.dng"), str(upright)]) == 0
    portrait, landscape = (json.loads(line) for line in capsys.readouterr().out.splitlines())
    assert (portrait["orientation"], portrait["width_px"], portrait["height_px"]) == (6, WIDTH, HEIGHT)
    assert landscape["orientation"] == 1


def test_fuse_keeps_the_sensors_pixels_and_turns_only_the_preview(tmp_path):
    results = {}
    for orientation in (None, 6):
        folder = _bracket(tmp_path / f"o{orientation}", orientation)
        assert main(["fuse", str(folder), "--out", str(folder / "hdr.exr")]) == 0
        results[orientation] = read_exr(folder / "hdr.exr"), _png(folder / "hdr.png")
    (upright_exr, upright_png), (portrait_exr, portrait_png) = results[None], results[6]
    assert upright_exr.attributes["orientation"] == 1 and upright_png.shape[:2] == (HEIGHT, WIDTH)
    assert portrait_exr.attributes["orientation"] == 6 and portrait_exr.shape == (HEIGHT, WIDTH)
    assert np.array_equal(portrait_exr.rgb(), upright_exr.rgb())  # sensor orientation, whatever the flag
    assert portrait_png.shape[:2] == (WIDTH, HEIGHT)  # portrait
    assert np.array_equal(portrait_png, np.rot90(upright_png, -1))  # turned 90 degrees clockwise


def test_fuse_warns_when_the_frames_orientations_differ(tmp_path):
    folder = tmp_path / "tilted"
    folder.mkdir()
    radiance = np.full((HEIGHT, WIDTH), 2.0e5)
    rng = np.random.default_rng(43)
    for name, exposure, orientation in (("a.dng", 0.002, 1), ("b.dng", 0.008, 6)):
        write_dng(folder / name, sensor_dn(radiance, exposure, rng), exposure_s=exposure, orientation=orientation)
    with pytest.warns(UserWarning, match=r"orientations differ \(1, 6;"):
        assert main(["fuse", str(folder), "--out", str(folder / "hdr.exr")]) == 0


@pytest.mark.parametrize("orientation", [1, 6])
def test_reconstruct_of_a_raw_records_the_orientation_and_turns_its_previews(tmp_path, capsys, orientation):
    frame = _bracket(tmp_path / "in", orientation) / "b.dng"
    out = tmp_path / "out"
    assert main(["reconstruct", str(frame), "--out", str(out)]) == 0
    result = read_exr(out / "b.exr")
    assert result.attributes["orientation"] == orientation and result.shape == (HEIGHT, WIDTH)
    preview_shape = (WIDTH, HEIGHT) if orientation == 6 else (HEIGHT, WIDTH)
    assert _png(out / "b.png").shape[:2] == preview_shape
    assert _png(out / "b-confidence.png").shape[:2] == preview_shape


def test_an_exr_that_hdrcam_wrote_of_a_turned_camera_keeps_its_orientation_downstream(tmp_path):
    from hdrcam.io.exr import write_exr
    from hdrcam.io.ldr_frame import read_ldr_frame_and_orientation

    frame = np.zeros((24, 40, 3), np.float32)
    frame[:, :8] = 0.5
    frame[3:6, 20:24] = 0.9
    exr = write_exr(tmp_path / "frame.exr", frame, channel_names=("R", "G", "B"), attributes={"orientation": 6})
    assert read_ldr_frame_and_orientation(exr)[1] == 6  # was 1: the reconstruction's previews lay sideways
    assert read_ldr_frame_and_orientation(write_exr(tmp_path / "odd.exr", frame, attributes={"orientation": 9}))[1] == 1
    scene = write_exr(tmp_path / "scene.exr", frame * 4.0, channel_names=("R", "G", "B"), attributes={"orientation": 8})
    assert main(["simulate", str(scene), "--psf", "dirac", "--out", str(tmp_path / "sim.exr")]) == 0
    assert read_exr(tmp_path / "sim.exr").attributes["orientation"] == 8  # was left out
