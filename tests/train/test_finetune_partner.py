"""``finetune`` trains a checkpoint's partner (NAME-partner.pt) too: where it goes, --no-partner, a partner
behind another PSF, and --resume after an interruption while the partner trained."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import OpenEXR
import pytest
import torch

from hdrcam.cli import main
from hdrcam.optics.psf_file import load_psf
from hdrcam.train import design
from hdrcam.train.checkpoint import SHIPPED_CHECKPOINT, partner_checkpoint, read_checkpoint, save_checkpoint

MEASURED_PSF = Path(__file__).resolve().parents[2] / "calibration" / "simulated-rank1" / "psf.exr"  # from calibrate
TINY = ["--steps", "2", "--crop", "64", "--batch", "1", "--device", "cpu"]


def _finetune(out: Path, *options) -> list[str]:
    return ["finetune", "--no-check", "--psf", str(MEASURED_PSF), *TINY, *options, "--out", str(out)]


def _summary(capsys) -> dict:
    return json.loads(capsys.readouterr().out.strip().splitlines()[-1])


def _distance(a: dict, b: dict) -> float:
    return sum(float((a[key].float() - b[key].float()).norm()) for key in a)


@pytest.fixture(scope="module")
def straight(tmp_path_factory) -> Path:
    """An uninterrupted finetune of the shipped checkpoint and its partner."""
    out = tmp_path_factory.mktemp("finetune") / "run"
    assert main(_finetune(out)) == 0
    return out


def test_finetune_writes_the_model_and_its_partner_behind_the_measured_psf(straight):
    model, partner = read_checkpoint(straight / "model.pt"), read_checkpoint(straight / "model-partner.pt")
    measured = load_psf(MEASURED_PSF)
    for state in (model, partner):
        assert state["step"] == 2 and state["config"]["psf"] == str(MEASURED_PSF)
        torch.testing.assert_close(state["psf"].numpy(), measured, rtol=0, atol=1e-6)
    assert partner["config"]["init_checkpoint"] == str(partner_checkpoint(SHIPPED_CHECKPOINT))
    assert {key: partner["config"][key] for key in ("steps", "batch", "crop_px", "learning_rate")} == {
        key: model["config"][key] for key in ("steps", "batch", "crop_px", "learning_rate")}
    assert partner["config"]["seed"] == model["config"]["seed"] + 1  # other batches than its model's
    shipped_partner = read_checkpoint(partner_checkpoint(SHIPPED_CHECKPOINT))["network"]
    shipped = read_checkpoint(SHIPPED_CHECKPOINT)["network"]
    assert _distance(partner["network"], model["network"]) > 0
    # fine-tuned from the partner's weights, not the main network's
    assert _distance(partner["network"], shipped_partner) < _distance(partner["network"], shipped) / 10
    assert (straight / "partner" / "model.pt").read_bytes() == (straight / "model-partner.pt").read_bytes()


def test_the_summary_names_the_partner_and_no_partner_trains_none(tmp_path, capsys):
    out = tmp_path / "alone"
    assert main(_finetune(out, "--no-partner")) == 0
    assert _summary(capsys)["partner"] is None
    assert (out / "model.pt").is_file()
    assert not (out / "model-partner.pt").exists() and not (out / "partner").exists()


def test_a_resume_follows_the_partner_choice_the_run_was_started_with(tmp_path, capsys):
    """A run made with --no-partner, resumed without it, trained a partner too (twice the time, unasked); one
    made with its partner, resumed with --no-partner, is told it was started otherwise."""
    alone, paired = tmp_path / "alone", tmp_path / "paired"
    assert main(_finetune(alone, "--no-partner")) == 0
    assert main(["finetune", "--no-check", "--out", str(alone), "--resume", "--steps", "3"]) == 0
    assert _summary(capsys)["partner"] is None
    assert read_checkpoint(alone / "model.pt")["step"] == 3
    assert not (alone / "model-partner.pt").exists() and not (alone / "partner").exists()
    assert main(_finetune(paired)) == 0
    capsys.readouterr()
    assert main(["finetune", "--no-check", "--out", str(paired), "--resume", "--steps", "3", "--no-partner"]) == 1
    error = capsys.readouterr().err.strip()
    assert error.count("\n") == 0 and "was started without --no-partner" in error, error
    assert read_checkpoint(paired / "model.pt")["step"] == 2  # nothing trained by the refused call


def test_a_partner_behind_another_psf_is_refused_before_any_training(tmp_path, capsys):
    start = tmp_path / "start.pt"
    shutil.copyfile(SHIPPED_CHECKPOINT, start)
    state = read_checkpoint(partner_checkpoint(SHIPPED_CHECKPOINT))
    state["psf"] = state["psf"].flip(-1).flip(-2).roll(3, -1).contiguous()  # another PSF
    save_checkpoint(partner_checkpoint(start), state)
    capsys.readouterr()
    assert main(_finetune(tmp_path / "run", "--checkpoint", str(start))) == 1
    error = capsys.readouterr().err.strip()
    assert error.count("\n") == 0 and "another PSF" in error and "start-partner.pt" in error, error
    assert "--no-partner" in error
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("when", ["after its first step", "before its first checkpoint"])
def test_resume_after_an_interrupted_partner_continues_the_partner(when, straight, tmp_path, capsys, monkeypatch):
    out = tmp_path / "run"
    train, steps = design.train, design._train_steps

    def partner_stopped(config, folder, **options):
        if folder.name == "partner" and when == "after its first step":
            train(config, folder, **options, stop_after=1)  # saves checkpoint.pt at step 1
            raise KeyboardInterrupt
        return train(config, folder, **options)

    def partner_stopped_at_once(config, folder, *arguments):
        if folder.name == "partner":
            raise KeyboardInterrupt  # config.json written, no checkpoint yet
        return steps(config, folder, *arguments)

    monkeypatch.setattr(design, "train", partner_stopped)
    monkeypatch.setattr(design, "_train_steps", partner_stopped_at_once if when != "after its first step" else steps)
    assert main(_finetune(out)) == 130
    assert (out / "model.pt").is_file() and not (out / "model-partner.pt").exists()
    assert (out / "partner" / "checkpoint.pt").is_file() == (when == "after its first step")
    main_log = (out / "log.jsonl").read_text()

    calls = []
    monkeypatch.setattr(design, "train", lambda config, folder, **options: calls.append(
        (folder.name, options["resume"])) or train(config, folder, **options))
    monkeypatch.setattr(design, "_train_steps", steps)
    capsys.readouterr()
    assert main(_finetune(out, "--resume")) == 0
    summary = _summary(capsys)
    assert summary["partner"] == {"run": str(out / "partner"), "model": str(out / "model-partner.pt")}
    assert calls == [("run", True), ("partner", when == "after its first step")]
    assert summary["last_step"] == {}  # the main network was not trained again
    assert (out / "log.jsonl").read_text() == main_log
    log = [json.loads(line) for line in (out / "partner" / "log.jsonl").read_text().splitlines()]
    expected = [json.loads(line) for line in (straight / "partner" / "log.jsonl").read_text().splitlines()]
    assert [line["step"] for line in log] == [1, 2]
    assert log[-1]["total"] == pytest.approx(expected[-1]["total"], rel=1e-5)  # as if never interrupted
    resumed, uninterrupted = read_checkpoint(out / "model-partner.pt"), read_checkpoint(straight / "model-partner.pt")
    assert resumed["step"] == 2
    assert _distance(resumed["network"], uninterrupted["network"]) < 1e-4


def _stop_the_partner_at_once(monkeypatch):
    """Interrupt (as SIGINT does) the partner's first step; returns the real step loop, to put back."""
    steps = design._train_steps

    def partner_stopped_at_once(config, folder, *arguments):
        if folder.name == "partner":
            raise KeyboardInterrupt
        return steps(config, folder, *arguments)

    monkeypatch.setattr(design, "_train_steps", partner_stopped_at_once)
    return steps


def test_a_partner_restarted_on_resume_keeps_the_runs_seed_plus_one(tmp_path, capsys, monkeypatch):
    """Made with --seed 5 and stopped before the partner saved anything, resumed without --seed: the partner still
    draws with seed 6 (the run's own seed + 1), not with the default's + 1."""
    out = tmp_path / "run"
    steps = _stop_the_partner_at_once(monkeypatch)
    assert main(_finetune(out, "--seed", "5")) == 130
    monkeypatch.setattr(design, "_train_steps", steps)
    assert main(_finetune(out, "--resume")) == 0
    capsys.readouterr()
    assert read_checkpoint(out / "checkpoint.pt")["config"]["seed"] == 5
    assert read_checkpoint(out / "partner" / "checkpoint.pt")["config"]["seed"] == 6


def test_a_partner_restarted_by_a_bare_resume_takes_the_main_runs_options(tmp_path, capsys, monkeypatch):
    """Stopped before the partner saved anything and resumed with --resume alone: the partner trains with the
    run's own steps, batch, crop and learning rate, not finetune's defaults (200 steps of 128 px crops)."""
    out = tmp_path / "run"
    steps = _stop_the_partner_at_once(monkeypatch)
    assert main(_finetune(out, "--lr", "1e-4")) == 130
    monkeypatch.setattr(design, "_train_steps", steps)
    assert main(["finetune", "--no-check", "--out", str(out), "--resume"]) == 0  # the run's own PSF (--psf was
    # required)
    capsys.readouterr()
    main_run = json.loads((out / "config.json").read_text())
    partner = json.loads((out / "partner" / "config.json").read_text())
    for field in ("steps", "batch", "crop_px", "learning_rate", "data", "psf"):
        assert partner[field] == main_run[field], field
    assert (partner["steps"], partner["crop_px"], partner["learning_rate"]) == (2, 64, 1e-4)


def test_a_run_stopped_before_its_first_checkpoint_resumes_from_step_0_with_its_options(tmp_path, capsys,
                                                                                       monkeypatch):
    """Nothing saved to continue: --resume starts it again with the options it was given (it said
    'checkpoint.pt does not exist', and a new run 'already holds a run')."""
    out = tmp_path / "run"
    steps = design._train_steps

    def stopped_at_once(config, folder, *arguments):
        raise KeyboardInterrupt

    monkeypatch.setattr(design, "_train_steps", stopped_at_once)
    assert main(_finetune(out, "--no-partner", "--lr", "1e-4")) == 130
    assert not (out / "checkpoint.pt").exists()
    monkeypatch.setattr(design, "_train_steps", steps)
    assert main(["finetune", "--no-check", "--out", str(out), "--resume", "--no-partner"]) == 0  # its PSF from
    # config.json
    capsys.readouterr()
    saved = read_checkpoint(out / "checkpoint.pt")["config"]
    assert (saved["steps"], saved["crop_px"], saved["learning_rate"]) == (2, 64, 1e-4)
    assert Path(saved["psf"]).resolve() == MEASURED_PSF.resolve()
    assert main(["finetune", "--no-check", "--out", str(tmp_path / "new")]) == 1  # a new run has no PSF to take
    assert "finetune needs --psf" in capsys.readouterr().err
    assert main(["finetune", "--no-check", "--out", str(tmp_path / "new"), "--resume"]) == 1
    assert "holds no run to resume; start one with --psf" in capsys.readouterr().err
    moved = tmp_path / "moved.exr"
    shutil.copy(MEASURED_PSF, moved)
    config = json.loads((out / "config.json").read_text())
    (out / "config.json").write_text(json.dumps({**config, "psf": str(tmp_path / "gone.exr")}))
    (out / "checkpoint.pt").unlink()  # the run as if stopped before its first checkpoint: config.json holds the PSF
    assert main(["finetune", "--no-check", "--out", str(out), "--resume", "--no-partner"]) == 1
    assert f"({tmp_path / 'gone.exr'}, its config.json) is gone and {out} saved no checkpoint holding it; give it, " \
        "or a copy of it, with --psf" in capsys.readouterr().err
    assert main(["finetune", "--no-check", "--psf", str(moved), "--out", str(out), "--resume", "--no-partner"]) == 0


def test_a_run_whose_psf_file_is_gone_resumes_behind_the_psf_its_checkpoint_holds(tmp_path, capsys):
    """As design does (a run folder copied to another machine, a calibration folder moved): finetune refused,
    'the PSF ... is gone; give it, or a copy of it, with --psf', though its checkpoint holds the PSF."""
    psf_path = tmp_path / "psf.exr"
    shutil.copyfile(MEASURED_PSF, psf_path)
    out = tmp_path / "run"
    assert main(["finetune", "--no-check", "--psf", str(psf_path), *TINY, "--no-partner", "--out", str(out)]) == 0
    psf_path.unlink()
    assert main(["finetune", "--no-check", "--steps", "3", "--no-partner", "--out", str(out), "--resume"]) == 0
    np.testing.assert_array_equal(read_checkpoint(out / "model.pt")["psf"].numpy(), load_psf(MEASURED_PSF))
    assert read_checkpoint(out / "model.pt")["step"] == 3


def test_a_damaged_log_line_and_a_calibration_folder_as_psf_are_one_line(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(_finetune(out, "--no-partner")) == 0
    with open(out / "log.jsonl", "a") as log:
        log.write('{"step": 3\n')
    capsys.readouterr()
    assert main(_finetune(out, "--no-partner", "--resume", "--steps", "3")) == 1
    assert "log.jsonl: line 3 is damaged" in capsys.readouterr().err
    assert main(["finetune", "--no-check", "--psf", str(MEASURED_PSF.parent), *TINY,
                 "--out", str(tmp_path / "other")]) == 1
    assert f"give the PSF inside it: {MEASURED_PSF}" in capsys.readouterr().err


def test_a_psf_file_changed_before_a_resume_is_refused(tmp_path, capsys):
    """The run trained behind one PSF; the same path holding another PSF is refused on --resume."""
    import numpy as np

    from hdrcam.io.exr import write_exr

    psf_path = tmp_path / "psf.exr"
    shutil.copyfile(MEASURED_PSF, psf_path)
    out = tmp_path / "run"
    argv = ["finetune", "--no-check", "--psf", str(psf_path), *TINY, "--no-partner", "--out", str(out)]
    assert main(argv) == 0
    psf = load_psf(MEASURED_PSF)
    write_exr(psf_path, np.roll(psf, 1, axis=-1).transpose(1, 2, 0), overwrite=True)
    capsys.readouterr()
    assert main(["finetune", "--no-check", "--psf", str(psf_path), "--steps", "3", "--no-partner", "--out", str(out),
                 "--resume"]) == 1
    assert "not the PSF run trained behind" in capsys.readouterr().err


def test_a_checkpoint_with_non_finite_weights_is_refused_in_one_line(tmp_path, capsys):
    """A diverged run's model (reconstruct crashed on it with exit 3 in a least-squares fit)."""
    state = read_checkpoint(SHIPPED_CHECKPOINT)
    name = next(key for key, value in state["network"].items() if value.is_floating_point())
    state["network"][name] = state["network"][name].clone().fill_(float("nan"))
    save_checkpoint(tmp_path / "diverged.pt", {key: value for key, value in state.items() if key != "format"})
    frame = tmp_path / "frame.exr"
    assert main(["simulate", "night", "--psf", "dirac", "--size", "32", "32", "--out", str(frame)]) == 0
    capsys.readouterr()
    assert main(["reconstruct", str(frame), "--checkpoint", str(tmp_path / "diverged.pt"), "--no-partner",
                 "--out", str(tmp_path / "r")]) == 1
    assert "NaN or Inf weights" in capsys.readouterr().err


def test_finetune_refuses_a_black_training_photograph_by_name_before_writing_a_run(tmp_path, capsys):
    photographs = tmp_path / "photographs"
    photographs.mkdir()
    OpenEXR.File({"type": OpenEXR.scanlineimage},
                 {"RGB": np.zeros((64, 64, 3), np.float32)}).write(str(photographs / "lens-cap.exr"))
    out = tmp_path / "run"
    assert main(_finetune(out, "--data", str(photographs))) == 1
    assert "lens-cap.exr: the photograph holds no light" in capsys.readouterr().err
    assert not out.exists()


def test_the_largest_seed_finetunes_its_partner_with_the_seed_wrapped_to_zero(tmp_path):
    out = tmp_path / "run"
    assert main(_finetune(out, "--seed", str(2 ** 32 - 1))) == 0  # the partner's seed + 1 was refused after
    assert json.loads((out / "partner" / "config.json").read_text())["seed"] == 0  # the main run had trained


def test_a_run_stopped_before_its_first_checkpoint_tells_its_config_from_config_json(tmp_path):
    from hdrcam.stages import _saved_config

    (tmp_path / "config.json").write_text(json.dumps({"seed": 7, "init_checkpoint": "A/model.pt"}))
    assert _saved_config(tmp_path) == {"seed": 7, "init_checkpoint": "A/model.pt"}  # was None: a resumed
    assert _saved_config(tmp_path / "nothing") is None  # finetune then took the shipped checkpoint's partner


def test_exporting_a_checkpoint_with_a_partner_says_how_to_export_the_partner(tmp_path):
    """... and says what the partner's export is for: reconstruct reads two ONNX files, but no TorchScript (it
    promised 'the same results' for a TorchScript pair that reconstruct refuses)."""
    with pytest.warns(UserWarning, match="has a partner, .*-partner.pt.*not TorchScript.*hdrcam export --checkpoint"):
        assert main(["export", "--format", "torchscript", "--out", str(tmp_path / "m.pt")]) == 0


def test_a_copied_run_finds_the_shipped_start_here_and_names_another_start_that_is_gone(tmp_path, monkeypatch,
                                                                                           capsys):
    from hdrcam.train.checkpoint import recorded_checkpoint

    elsewhere = Path("/another/install/hdrcam/checkpoints")
    assert recorded_checkpoint(elsewhere / SHIPPED_CHECKPOINT.name) == SHIPPED_CHECKPOINT
    partner = partner_checkpoint(SHIPPED_CHECKPOINT)
    assert recorded_checkpoint(elsewhere / partner.name) == partner
    assert recorded_checkpoint(tmp_path / "gone.pt") == tmp_path / "gone.pt"
    own = tmp_path / "own"
    own.mkdir()
    for path in (SHIPPED_CHECKPOINT, partner):
        shutil.copyfile(path, own / path.name)
    train = design.train

    def stopped_after_a_checkpoint(config, folder, **options):
        train(config, folder, **options, stop_after=1)
        raise KeyboardInterrupt

    monkeypatch.setattr(design, "train", stopped_after_a_checkpoint)
    run = tmp_path / "run"
    assert main(_finetune(run, "--checkpoint", str(own / SHIPPED_CHECKPOINT.name))) == 130
    monkeypatch.setattr(design, "train", train)
    shutil.rmtree(own)
    capsys.readouterr()
    assert main(_finetune(run, "--resume")) == 1  # it said only 'does not exist'
    error = capsys.readouterr().err.strip()
    assert error.count("\n") == 0 and "the checkpoint this run started from, is gone" in error


def test_a_run_from_a_checkpoint_without_a_partner_resumes_with_no_partner_too(tmp_path, capsys):
    """It recorded the wish (a partner) instead of what happened (none to train): --resume --no-partner was then
    refused as 'started without --no-partner'."""
    start = tmp_path / "start.pt"
    shutil.copyfile(SHIPPED_CHECKPOINT, start)  # no start-partner.pt beside it
    out = tmp_path / "run"
    assert main(_finetune(out, "--checkpoint", str(start))) == 0
    assert read_checkpoint(out / "model.pt")["config"]["finetune_partner"] is False
    assert main(["finetune", "--no-check", "--out", str(out), "--resume", "--steps", "3", "--no-partner"]) == 0
    assert read_checkpoint(out / "model.pt")["step"] == 3 and not (out / "partner").exists()
