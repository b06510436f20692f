"""A partner network's second opinion (``reconstruct(..., partner=)``, ``--partner``): only what both networks paint
is kept, with the mirror pass as before, and the partner must have been trained behind the same PSF."""

from __future__ import annotations

import json
import types

import numpy as np
import pytest
import torch

from hdrcam.api import network_windows, reconstruct
from hdrcam.cli import main
from hdrcam.errors import InputError
from hdrcam.io.exr import write_exr
from hdrcam.recon.tiling import CLIP_LEVEL, plan_regions
from hdrcam.train.checkpoint import SHIPPED_CHECKPOINT, load_model


class Painter(torch.nn.Module):
    """A stand-in network that paints every clipped channel at ``level`` x white and keeps the rest."""

    def __init__(self, level: float):
        super().__init__()
        self.level = level

    def forward(self, ldr: torch.Tensor):
        return types.SimpleNamespace(hdr=torch.where(ldr >= CLIP_LEVEL, ldr * self.level, ldr))


class _CountingProgress:
    def __init__(self):
        self.windows = 0

    def update(self, windows: int = 1) -> None:
        self.windows += windows


@pytest.fixture(scope="module")
def psf():
    return load_model().psf


def frame_with_a_window() -> np.ndarray:
    frame = np.full((64, 96, 3), 0.3, np.float32)
    frame[20:30, 40:60] = 1.0
    return frame


def test_only_what_both_networks_paint_is_kept(psf):
    frame = frame_with_a_window()
    bright, dim = (types.SimpleNamespace(network=Painter(level), psf=psf) for level in (8.0, 2.0))
    regions = plan_regions(frame, psf_radius_px=psf.shape[-1] // 2)
    progress = _CountingProgress()
    paired = reconstruct(frame, bright, partner=dim, progress=progress, regions=regions)
    alone = reconstruct(frame, dim)
    assert np.array_equal(paired.network_hdr, alone.network_hdr)  # the per-pixel minimum: the dimmer proposal
    assert float(paired.network_hdr[25, 50, 0]) == 2.0
    assert paired.tiles.passes == 4  # the frame and its mirror image, each through both networks
    assert progress.windows == network_windows(regions, psf, partner=True) == 2 * network_windows(regions, psf) > 0


def test_a_partner_trained_behind_another_psf_is_refused(psf):
    other = np.roll(psf, 1, axis=-1)
    model, partner = types.SimpleNamespace(network=Painter(2.0), psf=psf), types.SimpleNamespace(
        network=Painter(2.0), psf=other)
    with pytest.raises(InputError, match="another PSF"):
        reconstruct(frame_with_a_window(), model, partner=partner)


def test_cli_reconstruct_with_a_partner_runs_both(tmp_path, capsys):
    source = tmp_path / "frame.exr"
    write_exr(source, frame_with_a_window(), channel_names=("R", "G", "B"))
    assert main(["reconstruct", str(source), "--partner", str(SHIPPED_CHECKPOINT), "--out", str(tmp_path / "out")]) == 0
    report = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert "in 4 passes (the frame and its mirror image, each through 2 networks)" in report["work"]


def test_cli_refuses_a_partner_behind_another_psf_before_any_work(tmp_path, capsys):
    source = tmp_path / "frame.exr"
    write_exr(source, frame_with_a_window(), channel_names=("R", "G", "B"))
    windshield = SHIPPED_CHECKPOINT.parent / "windshield-fast.pt"
    assert main(["reconstruct", str(source), "--partner", str(windshield), "--out", str(tmp_path / "out")]) == 1
    error = capsys.readouterr().err
    assert "windshield-fast.pt was trained behind another PSF" in error and "internal error" not in error
    assert not (tmp_path / "out").exists()
    assert main(["evaluate", "--partner", str(windshield), "--count", "1", "--size", "64",
                 "--out", str(tmp_path / "ev")]) == 1
    assert "another PSF" in capsys.readouterr().err
