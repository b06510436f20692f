"""Arguments at and past their limits: out-of-range seeds, a point source inside the focal length, an export
onto its own checkpoint or under the other format's suffix, messages that name the file, and options that
the chosen method ignores."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from hdrcam.cli import main
from hdrcam.train.checkpoint import SHIPPED_CHECKPOINT

MAX_SEED = 2 ** 32 - 1

SEED_COMMANDS = {
    "psf": ["psf", "--profile", "simulated", "--psf-size", "15"],
    "simulate": ["simulate", "night", "--psf", "dirac", "--size", "32", "32"],
    "capture": ["capture", "bracket", "--camera", "sim", "--profile", "simulated", "--psf", "dirac", "--size", "32x32",
                "--stops", "2"],
    "demo": ["demo", "--size", "32", "32", "--finetune-steps", "0"],
    "finetune": ["finetune", "--steps", "1"],
    "design": ["design", "--steps", "1"],
    "evaluate": ["evaluate", "--count", "1"],
}
OUT_NAMES = {"psf": "p", "simulate": "s.exr", "capture": "b", "demo": "d", "finetune": "f", "design": "g",
             "evaluate": "e"}


def _usage_error(argv, capsys) -> str:
    with pytest.raises(SystemExit) as exit_info:
        main([str(word) for word in argv])
    error = capsys.readouterr().err
    assert exit_info.value.code == 2 and error.count("\n") == 1, error
    return error


@pytest.mark.parametrize("seed", ["-1", str(MAX_SEED + 1), "99999999999999999999"])
@pytest.mark.parametrize("command", sorted(SEED_COMMANDS))
def test_a_seed_outside_32_bits_is_a_usage_error_before_any_work(command, seed, tmp_path, capsys):
    out = tmp_path / OUT_NAMES[command]
    error = _usage_error([*SEED_COMMANDS[command], "--seed", seed, "--out", out], capsys)
    assert "--seed" in error and f"0 to {MAX_SEED}" in error
    assert not out.exists()


def test_simulate_runs_with_the_largest_seed(tmp_path):
    assert main([*SEED_COMMANDS["simulate"], "--seed", str(MAX_SEED), "--out", str(tmp_path / "s.exr")]) == 0


@pytest.mark.parametrize("depth", ["0.02", "0.01", "1e-9"])
def test_psf_refuses_a_source_at_or_inside_the_focal_length(depth, tmp_path, capsys):
    out = tmp_path / "p"
    assert main(["psf", "--profile", "simulated", "--psf-size", "15", "--depth", depth, "--out", str(out)]) == 1
    error = capsys.readouterr().err
    assert "--depth" in error and "focal length (0.02 m)" in error
    assert not out.exists()


def test_export_refuses_to_overwrite_its_own_checkpoint(tmp_path, capsys):
    checkpoint = tmp_path / "ck.pt"
    shutil.copyfile(SHIPPED_CHECKPOINT, checkpoint)
    before = checkpoint.read_bytes()
    assert main(["export", "--format", "torchscript", "--checkpoint", str(checkpoint), "--out", str(checkpoint),
                 "--overwrite"]) == 1
    assert "is also an input" in capsys.readouterr().err
    assert checkpoint.read_bytes() == before


@pytest.mark.parametrize("format_, name", [("torchscript", "m2.onnx"), ("onnx", "m2.pt"), ("torchscript", "m2")])
def test_export_refuses_an_out_suffix_of_another_format(format_, name, tmp_path, capsys):
    out = tmp_path / name
    assert main(["export", "--format", format_, "--out", str(out)]) == 1
    error = capsys.readouterr().err
    assert "--out" in error and f"--format {format_}" in error
    assert not out.exists()


def _write_exr(path, channels: dict, pitch_m: float = 32e-6):
    import OpenEXR

    OpenEXR.File({"pixel_pitch_m": pitch_m}, channels).write(str(path))
    return path


def test_fabricate_names_an_rgb_exr_given_as_height_map(tmp_path, capsys):
    plane = np.zeros((64, 64), np.float32)
    rgb = _write_exr(tmp_path / "rgb.exr", {"R": plane, "G": plane, "B": plane})
    assert main(["fabricate", str(rgb), "--profile", "simulated", "--out", str(tmp_path / "f")]) == 1
    error = capsys.readouterr().err
    assert str(rgb) in error and "single-channel" in error


@pytest.mark.parametrize("command", ["fabricate", "psf"])
def test_a_nan_height_map_is_named(command, tmp_path, capsys):
    heights = np.zeros((64, 64), np.float32)
    heights[3, 4] = np.nan
    nan_map = _write_exr(tmp_path / "nan.exr", {"height_m": heights})
    argv = {"fabricate": ["fabricate", str(nan_map)], "psf": ["psf", "--doe", str(nan_map), "--psf-size", "15"]}
    assert main([*argv[command], "--profile", "simulated", "--out", str(tmp_path / "o")]) == 1
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and str(nan_map) in error and "NaN" in error
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("option", [["--checkpoint", "trunc.pt"], ["--no-gate"]])
def test_destreak_by_fit_refuses_the_network_options(option, tmp_path, capsys):
    plane = np.full((64, 64), 0.5, np.float32)
    frame = _write_exr(tmp_path / "frame.exr", {"R": plane, "G": plane, "B": plane})
    assert main([str(word) for word in ["destreak", frame, *option, "--out", tmp_path / "d"]]) == 1
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and option[0] in error and "--method network" in error
    assert not (tmp_path / "d").exists()


@pytest.mark.parametrize("command", ["design", "finetune"])
def test_an_infinite_learning_rate_is_a_usage_error(command, tmp_path, capsys):
    """--lr inf trained to non-finite weights and a model.pt that reconstruct crashed on."""
    error = _usage_error([command, "--lr", "inf", "--out", tmp_path / "run"], capsys)
    assert "--lr" in error and "finite" in error and not (tmp_path / "run").exists()


@pytest.mark.parametrize("data", ["procedural:inf,x:1", "procedural:1e308,procedural:1e308"])
def test_data_weights_must_be_finite_and_add_up_to_a_finite_sum(data):
    from hdrcam.data.scenes import parse_mixture
    from hdrcam.errors import InputError

    with pytest.raises(InputError, match="finite weights"):
        parse_mixture(data)


def test_simulate_warns_when_a_scene_cannot_be_scaled_to_the_clipped_fraction_asked(tmp_path):
    from hdrcam.io.exr import write_exr

    write_exr(tmp_path / "uniform.exr", np.full((32, 32, 3), 0.3, np.float32))
    with pytest.warns(UserWarning, match="0 % of its pixels exceed 1, not the 1.5 % asked"):
        assert main(["simulate", str(tmp_path / "uniform.exr"), "--psf", "dirac", "--out",
                     str(tmp_path / "f.exr")]) == 0


@pytest.mark.parametrize("depth", ["inf", "1e400", "Infinity"])
def test_psf_refuses_a_source_at_infinity_as_a_usage_error(depth, tmp_path, capsys):
    """psf.json held "source_distance_m": Infinity, which is not JSON (strict readers refused the file)."""
    out = tmp_path / "p"
    error = _usage_error(["psf", "--profile", "simulated", "--psf-size", "15", "--depth", depth, "--out", out], capsys)
    assert error == f"hdrcam psf: error: argument --depth: must be finite, got {depth!r} (see 'hdrcam psf --help')\n"
    assert not out.exists()


@pytest.mark.parametrize("fraction", ["1", "inf", "1e400", "0", "nan"])
def test_simulate_refuses_a_clipped_fraction_outside_0_1_as_a_usage_error(fraction, tmp_path, capsys):
    out = tmp_path / "s.exr"
    error = _usage_error(["simulate", "night", "--psf", "dirac", "--clipped-fraction", fraction, "--out", out], capsys)
    assert error == (f"hdrcam simulate: error: argument --clipped-fraction: must lie between 0 and 1 (both excluded), "
                     f"got {fraction!r} (see 'hdrcam simulate --help')\n")
    assert not out.exists()


@pytest.mark.parametrize("size", ["99999999999999999999", "9223372036854775807", "10000000000"])
def test_psf_refuses_a_psf_size_beyond_any_memory_in_one_line(size, tmp_path, capsys):
    """Past a C ssize_t the memory estimate itself crashed (OverflowError in next_fast_len, exit 3)."""
    out = tmp_path / "p"
    assert main(["psf", "--psf-size", size, "--out", str(out)]) == 1  # the default profile: the chirp-z model
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and error.startswith("hdrcam psf: error: a chirp-z PSF of 3 wavelengths on ")
    assert f" and {size} px at 7 points per pixel needs about " in error and " TB of memory, more than the " in error
    assert not out.exists()
