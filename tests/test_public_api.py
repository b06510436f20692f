"""The public API: ``import hdrcam`` is light, ``help(hdrcam)`` lists the stages, and the stages run."""

from __future__ import annotations

import pydoc
import subprocess
import sys
from pathlib import Path

import numpy as np

import hdrcam

STAGES = ("capture_bracket", "fuse", "calibrate_psf", "design", "finetune", "reconstruct", "evaluate_checkpoints")


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


def test_fuse_is_the_library_merge():
    data = Path(__file__).parent / "hdr" / "data"
    image = hdrcam.fuse([data / "bracket-96x64"], profile="simulated", with_variance=True)
    np.testing.assert_array_equal(image.rgb, np.load(data / "bracket-96x64-fused-before-threads.npz")["rgb"])
