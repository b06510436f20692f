"""``design --init-doe CHECKPOINT``: the trained DOE starts from a saved design (e.g. the PSF-first rank-1 DOE of
Table 2, so that a lent GPU's minutes refine streaks rather than grow them from a flat plate)."""

from __future__ import annotations

import json

import pytest
import torch

from hdrcam.cli import main
from hdrcam.errors import InputError
from hdrcam.train.checkpoint import SHIPPED_CHECKPOINT, partner_checkpoint, read_checkpoint
from hdrcam.train.config import TrainConfig
from hdrcam.train.design import build_model

A7_RANK1 = SHIPPED_CHECKPOINT.parent / "table2" / "rank1.pt"  # a PSF-first rank-1 design for the A7 profile


def test_the_doe_starts_from_the_checkpoints_factors():
    config = TrainConfig(profile="simulated", doe="rank1", init_doe_checkpoint=str(SHIPPED_CHECKPOINT))
    heightmap = build_model(config, None, False).capture.simulator.heightmap
    saved = read_checkpoint(SHIPPED_CHECKPOINT)["doe"]["parameters"]
    assert torch.equal(heightmap.v.detach(), saved["v"]) and torch.equal(heightmap.q.detach(), saved["q"])
    fresh = build_model(TrainConfig(profile="simulated", doe="rank1"), None, False).capture.simulator.heightmap
    assert not torch.equal(fresh.v.detach(), saved["v"])  # without it, the seeded random start


@pytest.mark.parametrize("config, words", [
    (dict(doe="freeform", init_doe_checkpoint=str(SHIPPED_CHECKPOINT)), "holds a rank1 DOE"),
    (dict(doe="rank1", init_doe_checkpoint=str(partner_checkpoint(SHIPPED_CHECKPOINT))), "holds no trained DOE"),
    (dict(doe="rank1", init_doe_checkpoint=str(A7_RANK1)), "do not fit"),  # 1527 features, not 64
])
def test_a_doe_that_does_not_fit_the_run_is_refused_in_one_line(config, words):
    with pytest.raises(InputError, match=words) as refused:
        build_model(TrainConfig(profile="simulated", **config), None, False)
    assert "\n" not in str(refused.value)


def test_a_fixed_psf_has_no_doe_to_start():
    with pytest.raises(InputError, match="needs a DOE to train"):
        TrainConfig(psf="dirac", doe=None, init_doe_checkpoint=str(SHIPPED_CHECKPOINT))


def test_design_from_the_command_line_starts_from_the_doe_and_records_it(tmp_path, capsys):
    run = tmp_path / "run"
    tiny = ["--steps", "1", "--crop", "32", "--batch", "1", "--device", "cpu"]
    assert main(["design", "--doe", "rank1", "--init-doe", str(SHIPPED_CHECKPOINT), *tiny, "--out", str(run)]) == 0
    assert json.loads((run / "config.json").read_text())["init_doe_checkpoint"] == str(SHIPPED_CHECKPOINT)
    trained = read_checkpoint(run / "model.pt")["doe"]["parameters"]["v"]
    start = read_checkpoint(SHIPPED_CHECKPOINT)["doe"]["parameters"]["v"]
    assert float((trained - start).abs().max()) < 0.05  # one Adam step of 1e-2 from it (a random start: ~0.3)
    assert main(["design", "--init-doe", str(tmp_path / "missing.pt"), *tiny, "--out", str(tmp_path / "r2")]) == 1
    assert "--init-doe" in capsys.readouterr().err and not (tmp_path / "r2").exists()


def test_a_damaged_doe_checkpoint_is_named_by_its_option(tmp_path, capsys):
    damaged = tmp_path / "damaged.pt"
    damaged.write_bytes(b"\x00" * 64)
    tiny = ["--steps", "1", "--crop", "32", "--batch", "1", "--device", "cpu"]
    assert main(["design", "--doe", "rank1", "--init-doe", str(damaged), *tiny, "--out", str(tmp_path / "r")]) == 1
    error = capsys.readouterr().err.strip()
    assert "--init-doe" in error and "damaged.pt" in error and "\n" not in error
