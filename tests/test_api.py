"""The public API: ``hdrcam.reconstruct`` (lazy, so ``import hdrcam`` stays light) is :func:`hdrcam.api.reconstruct`,
and ``hdrcam evaluate`` (method ``hdrcam``) and ``hdrcam reconstruct`` both score / write exactly what it returns."""

from __future__ import annotations

import csv
import dataclasses
import subprocess
import sys
import types
from pathlib import Path

import numpy as np
import pytest
import torch

import hdrcam
import hdrcam.api
import hdrcam.evaluate.scoring as evaluation_run
from hdrcam.cli import main
from hdrcam.data.scenes import SceneSource
from hdrcam.evaluate.metrics import all_metrics
from hdrcam.io.exr import read_exr, write_exr
from hdrcam.recon.consistency import NoiseModel
from hdrcam.recon.tiling import CLIP_LEVEL
from hdrcam.sensor import fft_convolve
from hdrcam.train.checkpoint import load_model

REPOSITORY = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def model():
    return load_model()


def lamp_frame(psf: np.ndarray, height: int = 64, width: int = 80) -> np.ndarray:
    """A 3 x 3 lamp at 200 in a dim room (0.03) seen through ``psf``, clipped at 1 (no noise)."""
    scene = np.full((height, width, 3), 0.03, np.float32)
    scene[30:33, 38:41] = 200.0
    planes = torch.from_numpy(np.ascontiguousarray(scene.transpose(2, 0, 1)))
    blurred = fft_convolve(planes, torch.from_numpy(np.ascontiguousarray(psf, np.float32))).numpy()
    return np.clip(blurred.transpose(1, 2, 0), 0.0, 1.0).astype(np.float32)


class Spy:
    """Wraps a ``reconstruct``: records each call's frame and result; ``change`` may alter what is returned."""

    def __init__(self, target, change=None):
        self.target, self.change, self.calls = target, change, []

    def __call__(self, frame, model=None, **options):
        result = self.target(frame, model, **options)
        if self.change is not None:
            result = self.change(frame, result)
        self.calls.append(types.SimpleNamespace(frame=np.array(frame), model=model, options=options, result=result))
        return result


def test_package_exposes_reconstruct():
    assert "reconstruct" in hdrcam.__all__ and callable(hdrcam.reconstruct)
    assert all(hasattr(hdrcam, name) for name in hdrcam.__all__)


def test_import_hdrcam_alone_does_not_import_torch():
    code = ("import sys, hdrcam; before = 'torch' in sys.modules or 'hdrcam.api' in sys.modules; "
            "import hdrcam.api; print(before, 'torch' in sys.modules, hdrcam.__file__)")
    completed = subprocess.run([sys.executable, "-c", code], cwd=REPOSITORY, capture_output=True, text=True,
                               timeout=120, check=True)
    before, after_api, location = completed.stdout.split()
    assert Path(location).resolve().parent == REPOSITORY / "hdrcam"  # this checkout's package was tested
    assert before == "False", "import hdrcam imported torch (or hdrcam.api)"
    assert after_api == "True"  # the check can see torch: hdrcam.api does import it


def test_default_model_reconstructs_a_small_frame(model):
    frame = lamp_frame(model.psf)
    clipped = frame.max(axis=-1) >= CLIP_LEVEL
    assert clipped.any()
    result = hdrcam.reconstruct(frame)  # the shipped model, loaded on demand
    height, width = frame.shape[:2]
    assert result.hdr.shape == (height, width, 3) and result.hdr.dtype == np.float32
    assert result.confidence.shape == (height, width)
    assert result.network_hdr.shape == (height, width, 3)
    assert np.isfinite(result.hdr).all() and result.confidence.min() >= 0.0 and result.confidence.max() <= 1.0
    assert np.all(result.hdr[frame >= CLIP_LEVEL] >= 1.0)
    assert result.hdr.max() > 1.0  # a 200x lamp's strong streaks: a highlight above white is recovered
    # the default is the shipped checkpoint with its own PSF: the same as passing them explicitly
    explicit = hdrcam.api.reconstruct(frame, model, psf=model.psf)
    np.testing.assert_array_equal(result.hdr, explicit.hdr)
    np.testing.assert_array_equal(result.confidence, explicit.confidence)


def test_package_level_reconstruct_forwards_model_and_options(model, monkeypatch):
    spy = Spy(hdrcam.api.reconstruct)
    monkeypatch.setattr(hdrcam.api, "reconstruct", spy)
    frame = lamp_frame(model.psf, 48, 48)
    noise = NoiseModel(full_well_e=10000.0, read_noise_e=3.0)
    result = hdrcam.reconstruct(frame, model, psf=model.psf, noise=noise, adaptive=False)
    assert len(spy.calls) == 1 and spy.calls[0].model is model and result is spy.calls[0].result
    assert spy.calls[0].options == {"psf": model.psf, "noise": noise, "adaptive": False}


def test_evaluate_method_hdrcam_is_api_reconstruct(model, monkeypatch):
    """``evaluate_models`` (what ``hdrcam evaluate`` runs) imports ``reconstruct`` from hdrcam.api by name: it must
    be that very function, called once per scene and model, and its outputs must be what is scored. 96 px: the
    smallest procedural test crop whose capture clips (at 64 px nothing clips and the network never runs)."""
    assert evaluation_run.reconstruct is hdrcam.api.reconstruct
    spy = Spy(hdrcam.api.reconstruct)
    monkeypatch.setattr(evaluation_run, "reconstruct", spy)  # the name scoring actually calls
    rows, examples = evaluation_run.evaluate_models({"hdrcam": model}, SceneSource("procedural"), size_px=96, count=1)
    assert len(spy.calls) == 1
    call = spy.calls[0]
    assert call.frame.max() >= CLIP_LEVEL  # a frame with clipped pixels: the network ran
    assert call.model is model and np.array_equal(call.options["psf"], model.psf)
    (example,) = examples
    np.testing.assert_array_equal(call.frame, example.outputs["ldr"])
    np.testing.assert_array_equal(example.outputs["hdrcam"], call.result.hdr)
    np.testing.assert_array_equal(example.outputs["hdrcam-network"], call.result.network_hdr)
    scored = {row.method: row.metrics for row in rows}
    assert scored["hdrcam"] == all_metrics(call.result.hdr, example.truth)


def test_cli_evaluate_scores_what_api_reconstruct_returns(monkeypatch, tmp_path):
    """``hdrcam evaluate`` with the default checkpoint (method ``hdrcam``): make the reconstruction return the
    captured frame itself; the ``hdrcam`` row must then score exactly as the ``ldr`` row does."""
    spy = Spy(hdrcam.api.reconstruct, change=lambda frame, result: dataclasses.replace(result, hdr=frame.copy()))
    monkeypatch.setattr(evaluation_run, "reconstruct", spy)
    assert main(["evaluate", "--size", "96", "--count", "1", "--out", str(tmp_path / "eval")]) == 0
    assert len(spy.calls) == 1 and spy.calls[0].frame.max() >= CLIP_LEVEL
    rows = {row["method"]: row for row in csv.DictReader((tmp_path / "eval" / "metrics.csv").open())}
    assert {"ldr", "hdrcam", "hdrcam-network"} <= set(rows)
    metrics = ("psnr_linear", "pu21_psnr", "psnr_mu")
    assert all(float(rows["hdrcam"][name]) == pytest.approx(float(rows["ldr"][name]), abs=1e-6) for name in metrics)
    # ... and differs from the network's row, which the replacement did not touch
    assert any(abs(float(rows["hdrcam"][name]) - float(rows["hdrcam-network"][name])) > 1e-3 for name in metrics)


def test_cli_reconstruct_writes_what_api_reconstruct_returns(model, monkeypatch, tmp_path):
    """``hdrcam reconstruct`` imports ``reconstruct`` from hdrcam.api when it runs: patch it there, return a
    sentinel image and find exactly that image in the written EXR."""
    frame = lamp_frame(model.psf)
    write_exr(tmp_path / "frame.exr", frame)
    sentinel = np.full(frame.shape, 7.25, np.float32)
    spy = Spy(hdrcam.api.reconstruct, change=lambda frame, result: dataclasses.replace(result, hdr=sentinel))
    monkeypatch.setattr(hdrcam.api, "reconstruct", spy)
    assert main(["reconstruct", str(tmp_path / "frame.exr"), "--out", str(tmp_path / "out")]) == 0
    assert len(spy.calls) == 1
    np.testing.assert_array_equal(spy.calls[0].frame, frame)
    written = read_exr(tmp_path / "out" / "frame.exr")
    np.testing.assert_array_equal(written.rgb(), sentinel)
    np.testing.assert_array_equal(written.channels["confidence"], spy.calls[0].result.confidence)
