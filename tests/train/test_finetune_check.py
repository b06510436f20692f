"""A fine-tune is kept only where it scores at least as well as its start on held-out scenes behind the run's PSF
(hdrcam.train.finetune_check): otherwise model.pt holds the start networks behind that PSF, the fine-tuned ones
are kept beside it, and check.json says so."""

from __future__ import annotations

import json
from pathlib import Path

import torch

from hdrcam.cli import main
from hdrcam.optics.psf_file import load_psf
from hdrcam.train.checkpoint import SHIPPED_CHECKPOINT, partner_checkpoint, read_checkpoint, save_checkpoint
from hdrcam.train.finetune_check import check_finetune
from tests.train.test_finetune_partner import MEASURED_PSF

SHIPPED_PARTNER = partner_checkpoint(SHIPPED_CHECKPOINT)


def _behind_measured_psf(source: Path, target: Path, *, scrambled: bool) -> None:
    """``source``'s network behind the measured PSF (as finetune writes model.pt), its weights scrambled with
    seeded noise as large as each tensor's own spread when ``scrambled``."""
    state = read_checkpoint(source)
    psf = load_psf(MEASURED_PSF)
    network = dict(state["network"])
    if scrambled:
        generator = torch.Generator().manual_seed(0)
        network = {name: value + value.float().std().nan_to_num() * torch.randn(value.shape, generator=generator)
                   if value.is_floating_point() and value.numel() > 1 else value for name, value in network.items()}
    save_checkpoint(target, {**state, "network": network, "step": 2,
                             "psf": torch.from_numpy(psf / psf.sum(axis=(1, 2), keepdims=True))})


def test_a_fine_tune_that_scores_lower_falls_back_to_its_start(tmp_path):
    out = tmp_path / "run"
    out.mkdir()
    _behind_measured_psf(SHIPPED_CHECKPOINT, out / "model.pt", scrambled=True)
    _behind_measured_psf(SHIPPED_PARTNER, out / "model-partner.pt", scrambled=True)
    tuned = {name: read_checkpoint(out / name) for name in ("model.pt", "model-partner.pt")}
    check = check_finetune(out, SHIPPED_CHECKPOINT, SHIPPED_PARTNER, size_px=64)
    assert check.scenes == 8 and check.kept == "start" and check.finetuned_db < check.start_db
    for written, start, kept_as in (("model.pt", SHIPPED_CHECKPOINT, "model-finetuned.pt"),
                                    ("model-partner.pt", SHIPPED_PARTNER, "model-finetuned-partner.pt")):
        now, began, kept = read_checkpoint(out / written), read_checkpoint(start), read_checkpoint(out / kept_as)
        assert all(torch.equal(now["network"][name], began["network"][name]) for name in began["network"])
        assert torch.equal(now["psf"], tuned[written]["psf"])  # still behind the measured PSF
        assert all(torch.equal(kept["network"][name], tuned[written]["network"][name]) for name in kept["network"])
    record = json.loads((out / "check.json").read_text())
    assert record["kept"] == "start" and record["start_db"] > record["finetuned_db"]
    assert "did not help" in check.summary() and "model-finetuned.pt" in check.summary()


def test_a_fine_tune_that_scores_higher_is_kept_as_written(tmp_path):
    start, out = tmp_path / "start.pt", tmp_path / "run"
    out.mkdir()
    _behind_measured_psf(SHIPPED_CHECKPOINT, start, scrambled=True)  # a poor start the fine-tune improved on
    _behind_measured_psf(SHIPPED_CHECKPOINT, out / "model.pt", scrambled=False)
    written = (out / "model.pt").read_bytes()
    check = check_finetune(out, start, None, size_px=64)
    assert check.kept == "finetuned" and check.finetuned_db > check.start_db
    assert (out / "model.pt").read_bytes() == written and not (out / "model-finetuned.pt").exists()
    assert json.loads((out / "check.json").read_text())["kept"] == "finetuned"


def test_finetune_ends_with_its_check_and_reports_it(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["finetune", "--psf", str(MEASURED_PSF), "--steps", "1", "--crop", "64", "--batch", "1",
                 "--no-partner", "--device", "cpu", "--out", str(out)]) == 0
    captured = capsys.readouterr()
    summary = json.loads(captured.out.strip().splitlines()[-1])
    assert summary["check"]["scenes"] == 8 and summary["check"]["kept"] in ("start", "finetuned")
    assert "finetune check: the fine-tune" in captured.err
    assert json.loads((out / "check.json").read_text()) == summary["check"]


def test_a_check_folder_that_does_not_exist_is_refused_before_training(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["finetune", "--psf", str(MEASURED_PSF), "--steps", "1", "--crop", "64", "--batch", "1",
                 "--check-data", str(tmp_path / "missing"), "--out", str(out)]) == 1
    assert "missing" in capsys.readouterr().err and not out.exists()


def test_a_resumed_run_is_checked_again_and_its_newer_networks_kept_beside(tmp_path):
    """A learning rate of 1 wrecks the network in one step: the check falls back; resumed for a step more, the run
    is checked again, model.pt still the start's network, model-finetuned.pt the newer step's."""
    from hdrcam.stages import finetune

    out = tmp_path / "run"
    options = dict(steps=1, crop_px=64, batch=1, learning_rate=1.0, partner=False, device="cpu", quiet=True,
                   check_size_px=64)
    finetune(MEASURED_PSF, out, **options)
    assert json.loads((out / "check.json").read_text())["kept"] == "start"
    assert read_checkpoint(out / "model-finetuned.pt")["step"] == 1
    finetune(None, out, resume=True, steps=2, quiet=True, check_size_px=64)
    assert json.loads((out / "check.json").read_text())["kept"] == "start"
    assert read_checkpoint(out / "model-finetuned.pt")["step"] == 2
    now, began = read_checkpoint(out / "model.pt")["network"], read_checkpoint(SHIPPED_CHECKPOINT)["network"]
    assert all(torch.equal(now[name], began[name]) for name in began)


def test_photographs_kept_out_of_training_can_be_the_check(shared_data, tmp_path):
    out = tmp_path / "run"
    out.mkdir()
    _behind_measured_psf(SHIPPED_CHECKPOINT, out / "model.pt", scrambled=True)
    check = check_finetune(out, SHIPPED_CHECKPOINT, None, data=str(shared_data / "hdr"), size_px=64)
    assert check.data.endswith("hdr") and check.scenes == 6  # the six openexr-images photographs
    assert check.kept == ("start" if check.finetuned_db < check.start_db else "finetuned")
    assert json.loads((out / "check.json").read_text())["data"] == check.data


def test_a_finished_run_without_its_check_is_checked_when_resumed(tmp_path):
    """A run stopped during its check (or run with none) is checked by the next --resume, which trains nothing."""
    from hdrcam.stages import finetune

    out = tmp_path / "run"
    finetune(MEASURED_PSF, out, steps=1, crop_px=64, batch=1, partner=False, device="cpu", quiet=True, check=None)
    assert not (out / "check.json").exists()
    assert finetune(None, out, resume=True, quiet=True, check_size_px=64) == {}  # nothing left to train
    record = json.loads((out / "check.json").read_text())
    assert record["scenes"] == 8 and record["size_px"] == 64
    (out / "check.json").write_text('{"marker": "checked before"}')
    finetune(None, out, resume=True, quiet=True, check_size_px=64)  # checked already: not again
    assert json.loads((out / "check.json").read_text()) == {"marker": "checked before"}
