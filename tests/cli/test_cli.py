"""The command line: help, one-line errors with exit codes, psf and fabricate end to end."""

from __future__ import annotations

import json
import subprocess
import sys

import cv2
import numpy as np
import pytest

from hdrcam.cli import main
from hdrcam.io.exr import read_exr


def test_console_script_help_lists_the_commands():
    result = subprocess.run([sys.executable, "-m", "hdrcam", "--help"], capture_output=True, text=True)
    assert result.returncode == 0 and "psf" in result.stdout and "fabricate" in result.stdout


@pytest.mark.parametrize("command", ["psf", "fabricate", "capture", "ingest", "design", "finetune", "evaluate",
                                     "simulate", "reconstruct", "demo"])
def test_each_command_has_help(command, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main([command, "--help"])
    assert exit_info.value.code == 0 and "usage: hdrcam" in capsys.readouterr().out


@pytest.mark.parametrize("argv", [["psf", "--bogus"], ["psf", "--depth", "-1"], ["psf", "--psf-size", "x"],
                                  ["nosuchcommand"], [], ["fabricate"]])
def test_bad_arguments_give_one_line_and_exit_2(argv, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    error = capsys.readouterr().err
    assert exit_info.value.code == 2 and error.count("\n") == 1 and "error:" in error


def test_psf_writes_unit_sum_psf_heightmap_png_and_record(tmp_path, capsys):
    out = tmp_path / "psf"
    assert main(["psf", "--profile", "simulated", "--out", str(out)]) == 0
    psf = read_exr(out / "psf.exr")
    rgb = psf.rgb()
    assert rgb.shape == (63, 63, 3)
    np.testing.assert_allclose(rgb.sum(axis=(0, 1)), 1.0, rtol=1e-5)
    assert np.unravel_index(np.argmax(rgb[..., 1]), (63, 63)) == (31, 31)
    assert psf.attributes["pixel_pitch_m"] == pytest.approx(5.97e-6, rel=1e-6)
    heights = read_exr(out / "heightmap.exr")
    assert heights.single().shape == (64, 64) and heights.attributes["pixel_pitch_m"] == pytest.approx(32e-6, rel=1e-6)
    record = json.loads((out / "psf.json").read_text())
    assert record["grid_size"] == 720 and record["upsample"] == 2 and record["lens_phase_aliased"] is False
    assert main(["psf", "--profile", "simulated", "--upsample", "1", "--allow-aliasing", "--psf-size", "15",
                 "--out", str(tmp_path / "aliased")]) == 0  # a file that says so (psf.json held only upsample)
    assert json.loads((tmp_path / "aliased" / "psf.json").read_text())["lens_phase_aliased"] is True
    assert (out / "psf.png").read_bytes()[:4] == b"\x89PNG"
    assert "energy in the 7 px centre" in capsys.readouterr().out


def test_psf_refuses_to_overwrite_and_leaves_existing_files_untouched(tmp_path, capsys):
    out = tmp_path / "psf"
    assert main(["psf", "--profile", "simulated", "--doe", "none", "--out", str(out)]) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    assert main(["psf", "--profile", "simulated", "--out", str(out)]) == 1
    assert "already exists" in capsys.readouterr().err
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


def test_defocused_depth_and_clear_aperture(tmp_path):
    assert main(["psf", "--profile", "simulated", "--doe", "none", "--out", str(tmp_path / "a")]) == 0
    assert main(["psf", "--profile", "simulated", "--doe", "none", "--depth", "0.3", "--out", str(tmp_path / "b")]) == 0
    focused = read_exr(tmp_path / "a" / "psf.exr").rgb()[..., 1]
    defocused = read_exr(tmp_path / "b" / "psf.exr").rgb()[..., 1]
    assert defocused.max() < focused.max() / 5


def test_damaged_or_wrong_heightmap_gives_one_line_and_exit_1(tmp_path, shared_data, capsys):
    damaged = next(p for p in (shared_data / "damaged-exr").iterdir() if p.name.startswith("asan"))
    assert main(["psf", "--profile", "simulated", "--doe", str(damaged), "--out", str(tmp_path / "x")]) == 1
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and "not a readable OpenEXR file" in error
    assert not (tmp_path / "x").exists()
    rgb_image = shared_data / "hdr" / "Desk.exr"
    assert main(["fabricate", str(rgb_image), "--profile", "simulated", "--out", str(tmp_path / "f")]) == 1
    assert "pixel_pitch_m" in capsys.readouterr().err


def test_fabricate_masks_report_and_psf_of_the_quantised_doe(tmp_path, capsys):
    assert main(["psf", "--profile", "simulated", "--out", str(tmp_path / "p")]) == 0
    assert main(["fabricate", str(tmp_path / "p" / "heightmap.exr"), "--profile", "simulated", "--simulate",
                 "--out", str(tmp_path / "f")]) == 0
    report = json.loads((tmp_path / "f" / "report.json").read_text())
    assert report["masks"] == 4 and len(report["mask_etch_depths_m"]) == 4
    assert 0.95 < report["quantisation_strehl_at_design_wavelength"] <= 1.0
    assert max(report["psf_l1_difference_rgb"]) < 0.1
    assert sorted(p.name for p in (tmp_path / "f").glob("mask_*.png")) == [f"mask_{i}_of_4.png" for i in range(1, 5)]
    assert report["masks_mark"].startswith("white = etch")
    etched_steps = sum(2 ** (i - 1) * (cv2.imread(str(tmp_path / "f" / f"mask_{i}_of_4.png"), cv2.IMREAD_GRAYSCALE) > 0)
                       for i in range(1, 5))
    relief_m = (15 - etched_steps) * report["step_m"]  # what etching by the masks leaves above the deepest etch
    quantised = read_exr(tmp_path / "f" / "heightmap_quantised.exr").channels
    np.testing.assert_allclose(relief_m, next(iter(quantised.values())), atol=1e-12)  # was inverted: PSF turned 180
    # the quantised map is itself a DOE the PSF command accepts
    assert main(["psf", "--profile", "simulated", "--doe", str(tmp_path / "f" / "heightmap_quantised.exr"),
                 "--out", str(tmp_path / "q")]) == 0
    np.testing.assert_allclose(read_exr(tmp_path / "q" / "psf.exr").rgb(),
                               read_exr(tmp_path / "f" / "psf_quantised.exr").rgb(), atol=1e-6)


def test_missing_cuda_device_and_nan_heightmap_are_clear_errors(tmp_path, capsys):
    import OpenEXR
    import torch

    if not torch.cuda.is_available():
        assert main(["psf", "--profile", "simulated", "--device", "cuda", "--out", str(tmp_path / "c")]) == 1
        assert "no CUDA device" in capsys.readouterr().err
    heights = np.zeros((64, 64), np.float32)
    heights[3, 4] = np.nan
    OpenEXR.File({"pixel_pitch_m": 32e-6}, {"height_m": heights}).write(str(tmp_path / "nan.exr"))
    assert main(["psf", "--profile", "simulated", "--doe", str(tmp_path / "nan.exr"), "--out", str(tmp_path / "n")]) == 1
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and "NaN" in error and not (tmp_path / "n").exists()
