"""Options that do not apply to what they were given are refused or named, never silently ignored."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hdrcam.cli import main
from hdrcam.io.exr import write_exr

CHECKPOINTS = Path(__file__).resolve().parents[2] / "hdrcam" / "checkpoints"


def _one_line(capsys) -> str:
    error = capsys.readouterr().err.strip()
    assert error.count("\n") == 0, error
    return error


def test_simulate_refuses_size_for_a_scene_file(tmp_path, capsys):
    scene = write_exr(tmp_path / "scene.exr", np.full((40, 48, 3), 0.5, np.float32))
    assert main(["simulate", str(scene), "--psf", "dirac", "--size", "16", "16", "--out", str(tmp_path / "f.exr")]) == 1
    assert "--size sets the procedural 'night' scene" in _one_line(capsys)  # it wrote a 40 x 48 frame, exit 0
    assert not (tmp_path / "f.exr").exists()


def test_demo_refuses_negative_finetune_steps(tmp_path, capsys):
    with pytest.raises(SystemExit) as stop:
        main(["demo", "--finetune-steps", "-3", "--out", str(tmp_path / "demo")])  # it skipped fine-tuning, exit 0
    assert stop.value.code == 2 and "--finetune-steps" in capsys.readouterr().err


def test_reconstruct_refuses_the_windshield_network(tmp_path, capsys):
    frame = write_exr(tmp_path / "frame.exr", np.full((32, 32, 3), 0.5, np.float32))
    windshield = CHECKPOINTS / "windshield-fast.pt"
    assert main(["reconstruct", str(frame), "--checkpoint", str(windshield), "--out", str(tmp_path / "r")]) == 1
    assert "a windshield network" in _one_line(capsys)  # it ran, its streak check behind a 2-point star
    assert not (tmp_path / "r").exists()
    exported = tmp_path / "windshield.onnx"  # its export held the HDR estimate, which nothing runs
    assert main(["export", "--format", "onnx", "--checkpoint", str(windshield), "--out", str(exported)]) == 1
    assert "a windshield network (design --psf windshield): destreak runs it from this checkpoint" in \
        _one_line(capsys) and not exported.exists()
    pytest.importorskip("onnxruntime")
    import json

    from hdrcam.recon.export import export_onnx
    from hdrcam.train.checkpoint import load_model

    model = load_model(windshield)  # an export made before export refused it
    export_onnx(model.network, exported, {"hdrcam_psf": json.dumps(model.psf.tolist()), "hdrcam_profile": model.profile,
                                          "hdrcam_preset": model.preset, "hdrcam_fixed_psf": "windshield"})
    assert main(["reconstruct", str(frame), "--checkpoint", str(exported), "--out", str(tmp_path / "r")]) == 1
    assert "destreak runs it from the checkpoint it was exported from" in _one_line(capsys)


def test_vgg_weights_for_a_preset_without_vgg_are_named_as_unused(tmp_path):
    from hdrcam.train.checkpoint import load_model

    with pytest.warns(UserWarning, match="has no VGG features; the weights are not used"):
        model = load_model(None, vgg_weights=tmp_path / "missing-vgg19.pth")
    assert model.preset == "fast"


def test_reconstruct_refuses_a_tile_below_16_px_before_loading_anything(tmp_path, capsys):
    with pytest.raises(SystemExit) as stop:  # it was refused after the model loaded, beside a progress bar
        main(["reconstruct", str(tmp_path / "frame.exr"), "--tile", "8", "--out", str(tmp_path / "r")])
    assert stop.value.code == 2 and "--tile: must be at least 16" in capsys.readouterr().err


def test_capture_bracket_refuses_a_region_of_interest_without_auto(tmp_path, capsys):
    """--roi is the region --auto meters; without --auto it was taken and ignored (a fixed bracket, exit 0)."""
    out = tmp_path / "bracket"
    with pytest.raises(SystemExit) as stop:  # a usage error naming the option, not the API's roi/auto fields
        main(["capture", "bracket", "--camera", "sim", "--profile", "simulated", "--size", "64x48",
              "--roi", "0,0,32,32", "--out", str(out)])
    assert stop.value.code == 2 and _one_line(capsys) == (
        "hdrcam capture bracket: error: argument --roi: the region --auto meters; give --auto with it, or leave "
        "--roi out (see 'hdrcam capture bracket --help')")
    assert not out.exists()
