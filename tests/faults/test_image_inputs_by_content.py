"""reconstruct, simulate and evaluate on image files whose name is not their format, Radiance frames with
primaries, 12-bit TIFFs, empty and non-regular files, and a wide-gamut photograph near float32's limit: the pixels
the file stores, or one line and exit 1 - never scrambled pixels with exit 0, nor an internal error."""

from __future__ import annotations

import os

import cv2
import numpy as np
import OpenEXR
import pytest

from hdrcam.cli import main
from hdrcam.io.exr import read_exr

REC2020 = (0.708, 0.292, 0.170, 0.797, 0.131, 0.046, 0.3127, 0.3290)


def _mild(height: int = 48, width: int = 64) -> np.ndarray:
    """A frame with no clipped pixel (reconstruct passes it through): R, G rising across and down, B flat."""
    y, x = np.mgrid[0:height, 0:width].astype(np.float32)
    return np.stack([0.4 + 0.1 * x / width, 0.4 + 0.05 * y / height, np.full_like(x, 0.38)], -1)


def _radiance(path, rgb: np.ndarray, header_line: bytes = b"") -> np.ndarray:
    """``rgb`` written as a Radiance file with ``header_line`` added; the values it stores (OpenCV's decoding)."""
    written = path.with_name("written.hdr")  # OpenCV picks its writer by the suffix
    cv2.imwrite(str(written), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    stored = cv2.cvtColor(cv2.imread(str(written), cv2.IMREAD_ANYDEPTH | cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    data = written.read_bytes()
    end = data.index(b"\n\n")
    path.write_bytes(data[:end + 1] + header_line + data[end + 1:])
    written.unlink()
    return stored


def _error_lines(capsys) -> list[str]:
    return [line for line in capsys.readouterr().err.splitlines() if "error" in line]


def test_reconstruct_takes_frames_by_their_content_and_as_stored(tmp_path, capsys):
    import tifffile

    primaries = b"PRIMARIES= " + " ".join(map(str, REC2020)).encode() + b"\n"
    expected = {"primaries": _radiance(tmp_path / "primaries.hdr", _mild(), primaries),  # 13 % off before
                "radiance": _radiance(tmp_path / "radiance.exr", _mild())}  # refused: '<python_buffer>'
    counts = np.round(_mild() * 65535).astype(np.uint16)
    tifffile.imwrite(tmp_path / "planar.png", np.moveaxis(counts, -1, 0), photometric="rgb", planarconfig="separate")
    expected["planar"] = counts.astype(np.float32) / 65535.0  # scrambled by OpenCV before, 0.98 off
    twelve = np.round(_mild() * 4095).astype(np.uint16)
    tifffile.imwrite(tmp_path / "twelve.tif", twelve, photometric="rgb", bitspersample=12)
    expected["twelve"] = twelve.astype(np.float32) / 4095.0  # / 65535 before: 16x too dark
    for name, path in (("primaries", "primaries.hdr"), ("radiance", "radiance.exr"), ("planar", "planar.png"),
                       ("twelve", "twelve.tif")):
        assert main(["reconstruct", str(tmp_path / path), "--out", str(tmp_path / f"out-{name}")]) == 0, name
        stem = path.rsplit(".", 1)[0]
        np.testing.assert_array_equal(read_exr(tmp_path / f"out-{name}" / f"{stem}.exr").rgb(), expected[name])


def test_an_empty_file_a_device_and_a_fifo_are_one_line_saying_what_they_are(tmp_path, capsys):
    (tmp_path / "empty.exr").write_bytes(b"")
    os.mkfifo(tmp_path / "fifo.exr")
    for path, reason in ((tmp_path / "empty.exr", "an empty file (0 bytes)"),
                         ("/dev/null", "not a regular file (a device, pipe or socket)"),
                         (tmp_path / "fifo.exr", "not a regular file (a device, pipe or socket)")):
        capsys.readouterr()
        assert main(["reconstruct", str(path), "--out", str(tmp_path / "out")]) == 1
        assert _error_lines(capsys) == [f"hdrcam reconstruct: error: {path}: {reason}"]
        assert main(["simulate", str(path), "--out", str(tmp_path / "frame.exr"), "--psf", "dirac"]) == 1
        assert _error_lines(capsys) == [f"hdrcam simulate: error: {path}: {reason}"]


def test_simulate_reads_a_planar_tiff_named_hdr_as_the_scene_it_stores(tmp_path, capsys):
    import tifffile

    scene = _mild() * 2.0
    scene[10, 50] = (60.0, 10.0, 2.0)
    scene[30:33, 20:23] = 20.0
    tifffile.imwrite(tmp_path / "scene.hdr", np.moveaxis(scene, -1, 0), photometric="rgb", planarconfig="separate")
    assert main(["simulate", str(tmp_path / "scene.hdr"), "--out", str(tmp_path / "frame.exr"), "--truth",
                 str(tmp_path / "truth.exr"), "--psf", "dirac"]) == 0
    ratio = read_exr(tmp_path / "truth.exr").rgb() / scene  # the scene times one constant
    np.testing.assert_allclose(ratio, ratio[0, 0, 0], rtol=1e-6)


def test_evaluate_leaves_out_a_wide_gamut_photograph_beyond_float32_naming_it(tmp_path, capsys):
    """It exited 3: "internal error: ValueError: high <= 0", after numpy's "invalid value encountered in divide"."""
    data = tmp_path / "data"
    data.mkdir()
    rng = np.random.default_rng(0)
    for name, peak in (("lamps", 1.0), ("wide", 3e38)):
        photo = rng.lognormal(0.0, 1.5, (96, 96, 3)).astype(np.float32)
        photo[40, 40] = (peak, 1.0, 1.0)
        OpenEXR.File({"type": OpenEXR.scanlineimage, "chromaticities": REC2020}, {"RGB": photo}).write(
            str(data / f"{name}.exr"))
    capsys.readouterr()
    with pytest.warns(UserWarning) as warned:
        assert main(["evaluate", "--data", str(data), "--size", "64", "--no-partner", "--out",
                     str(tmp_path / "out")]) == 0
    assert f"{data / 'wide.exr'}: not evaluated - its values (up to 3e+38) leave float32's range (3.4e+38) once its " \
           "primaries are converted to Rec. 709; scale the image down (its absolute scale does not matter to hdrcam)" \
           in [str(warning.message) for warning in warned]
    assert not [warning for warning in warned if not issubclass(warning.category, UserWarning)]  # numpy's own
    assert "error" not in capsys.readouterr().err
    assert "1 of 2 photographs scored" in (tmp_path / "out" / "summary.md").read_text(encoding="utf-8")
