"""``design`` / ``finetune --linear-gain-weight W``: the loss term that measures what the evaluation measures
(hdrcam.recon.losses.linear_gain_loss) is recorded with the run, trained with, and held on --resume."""

from __future__ import annotations

import json

import pytest

from hdrcam.cli import main
from hdrcam.train.checkpoint import SHIPPED_CHECKPOINT

TINY = ["--steps", "1", "--crop", "32", "--batch", "1", "--device", "cpu"]


def test_the_weight_is_recorded_logged_and_held_on_resume(tmp_path, capsys):
    run = tmp_path / "run"
    assert main(["design", "--psf", "dirac", "--linear-gain-weight", "0.05", *TINY, "--out", str(run)]) == 0
    assert json.loads((run / "config.json").read_text())["weights"]["linear_gain"] == 0.05
    logged = json.loads((run / "log.jsonl").read_text().splitlines()[-1])
    assert "linear_gain" in logged and logged["total"] == pytest.approx(
        sum(value for key, value in logged.items() if key not in ("step", "total", "lr", "seconds")), abs=1e-5)
    capsys.readouterr()
    grown = ["--steps", "2", "--device", "cpu", "--resume", "--out", str(run)]
    assert main(["design", "--linear-gain-weight", "0.1", *grown]) == 1  # another weight: refused
    assert "\n" not in capsys.readouterr().err.strip()
    assert main(["design", *grown]) == 0  # its own weight, kept
    assert "linear_gain" in json.loads((run / "log.jsonl").read_text().splitlines()[-1])


def test_finetune_takes_it_and_without_it_a_run_keeps_the_papers_losses(tmp_path):
    plain = tmp_path / "plain"
    assert main(["design", "--psf", "dirac", *TINY, "--out", str(plain)]) == 0
    assert json.loads((plain / "config.json").read_text())["weights"]["linear_gain"] == 0.0
    assert "linear_gain" not in json.loads((plain / "log.jsonl").read_text().splitlines()[-1])
    tuned = tmp_path / "tuned"
    assert main(["finetune", "--checkpoint", str(SHIPPED_CHECKPOINT), "--psf", str(plain / "psf.exr"), "--no-partner",
                 "--no-check", "--linear-gain-weight", "0.05", *TINY, "--out", str(tuned)]) == 0
    assert json.loads((tuned / "config.json").read_text())["weights"]["linear_gain"] == 0.05
    assert "linear_gain" in json.loads((tuned / "log.jsonl").read_text().splitlines()[-1])


@pytest.mark.parametrize("value", ["-0.1", "inf", "nan", "x"])
def test_a_weight_no_run_can_have_is_a_usage_error(tmp_path, value, capsys):
    with pytest.raises(SystemExit) as stopped:
        main(["design", "--linear-gain-weight", value, *TINY, "--out", str(tmp_path / "r")])
    assert stopped.value.code == 2 and not (tmp_path / "r").exists()
    assert "--linear-gain-weight" in capsys.readouterr().err
