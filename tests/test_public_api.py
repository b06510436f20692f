"""The public API: ``import hdrcam`` is light, ``help(hdrcam)`` lists the stages, and the stages run."""

from __future__ import annotations

import pydoc
import subprocess
import sys
from pathlib import Path

import numpy as np

import hdrcam

STAGES = ("capture_bracket", "fuse", "calibrate_psf", "find_bad_pixels", "design", "finetune", "reconstruct",
          "evaluate_checkpoints")


def test_help_lists_every_stage_with_a_documented_function():
    text = pydoc.render_doc(hdrcam, renderer=pydoc.plaintext)
    for name in STAGES:
        function = getattr(hdrcam, name)
        assert f"{name}(" in text and len(function.__doc__) > 200, name
    done = subprocess.run([sys.executable, "-c", "import hdrcam; help(hdrcam)"], capture_output=True, text=True,
                          check=True)
    assert all(f"{name}(" in done.stdout for name in STAGES)


def test_capture_then_fuse_through_the_api(tmp_path):
    bracket, darks = hdrcam.capture_bracket(tmp_path / "bracket", camera="sim", profile="simulated", scene="night",
                                            psf="dirac", size_px=(96, 64), stops=3, ev_step=3.0, darks=True, seed=2)
    assert len(bracket.frames) == 3 and len(darks.frames) == 3
    assert (tmp_path / "bracket" / "bracket.json").is_file()
    image = hdrcam.fuse([tmp_path / "bracket"], profile="simulated", darks=tmp_path / "bracket" / "darks",
                        camera_rgb=True)
    assert image.rgb.shape == (64, 96, 3) and image.rgb.dtype == np.float32 and np.isfinite(image.rgb).all()
    assert image.colour == "camera RGB" and len(image.merge.exposures_s) == 3


def test_capture_through_the_api_is_the_command_s_capture(tmp_path):
    """The command calls the stage: same manifest options, never an overwrite, resume of a complete capture
    refused, and the command's lines through ``log``."""
    import json

    import pytest

    from hdrcam.errors import InputError, OutputExistsError

    lines = []
    options = dict(camera="sim", profile="simulated", scene="point", size_px=(64, 48), stops=2, ev_step=3.0)
    bracket, _ = hdrcam.capture_bracket(tmp_path / "b", log=lines.append, **options)
    manifest = json.loads((tmp_path / "b" / "bracket.json").read_text())
    assert len(manifest["options"]["profile_sha256"]) == 64 and manifest["status"] == "complete"
    assert lines[0].startswith("camera: ") and sum(".dng" in line for line in lines) == 2
    assert lines[3].startswith("2 frames in ")
    with pytest.raises(OutputExistsError, match="never overwritten"):
        hdrcam.capture_bracket(tmp_path / "b", **options)
    with pytest.raises(InputError, match="nothing to resume"):
        hdrcam.capture_bracket(tmp_path / "b", resume=True, **options)


def test_fuse_is_the_library_merge():
    data = Path(__file__).parent / "hdr" / "data"
    from hdrcam.hdr.fuse import fuse
    from hdrcam.profiles import load_profile

    image = hdrcam.fuse([data / "bracket-96x64"], profile="simulated", with_variance=True)
    library = fuse([data / "bracket-96x64"], load_profile("simulated").camera, with_variance=True)
    np.testing.assert_array_equal(image.rgb, library.rgb)
    assert image.rgb.shape == (64, 96, 3) and np.isfinite(image.rgb).all()


def test_finetune_design_and_evaluate_through_the_api(tmp_path):
    from hdrcam.io.exr import write_exr
    from hdrcam.train.checkpoint import load_model

    psf_path = write_exr(tmp_path / "psf.exr", load_model().psf.transpose(1, 2, 0), channel_names=("R", "G", "B"))
    tuned = hdrcam.finetune(psf_path, tmp_path / "tuned", steps=2, batch=1, crop_px=32, device="cpu", quiet=True,
                            check=None)
    designed = hdrcam.design(tmp_path / "designed", psf="dirac", steps=1, batch=1, crop_px=32, device="cpu", quiet=True)
    assert tuned["step"] == 2 and designed["step"] == 1 and np.isfinite(tuned["total"])
    assert (tmp_path / "tuned" / "model.pt").is_file() and (tmp_path / "designed" / "model.pt").is_file()
    rows, examples = hdrcam.evaluate_checkpoints({"tuned": tmp_path / "tuned" / "model.pt"}, size_px=64, count=1)
    methods = {row.method for row in rows}
    assert methods == {"ldr", "hdrcnn-blend", "tuned", "tuned-network"} and len(examples) == 1
    assert all(np.isfinite(row.metrics["psnr_linear"]) for row in rows)
