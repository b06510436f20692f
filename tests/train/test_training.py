"""Training: optimisation reduces the loss, the optics gradient trains the DOE, resume is exact."""

import json

import numpy as np
import pytest
import torch

from hdrcam.errors import InputError
from hdrcam.io.exr import read_exr, write_exr
from hdrcam.optics.analytic import dirac, star
from hdrcam.optics.energy import energy_regulariser
from hdrcam.profiles import load_profile
from hdrcam.recon.losses import LossWeights, reconstruction_loss
from hdrcam.recon.network import ReconstructionNet
from hdrcam.recon.presets import preset
from hdrcam.train.checkpoint import load_model, read_checkpoint
from hdrcam.train.config import TrainConfig
from hdrcam.train.design import train
from hdrcam.train.optical_capture import OpticalCapture, fixed_psf


def test_a_few_steps_reduce_the_loss_on_a_fixed_batch():
    torch.manual_seed(0)
    radiance = torch.rand(2, 3, 32, 32) * 0.8
    radiance[:, :, 10:13, 10:13] = 40.0
    capture = OpticalCapture(load_profile("simulated"), psf=star(15, points=8))
    ldr, _ = capture(torch.nn.functional.pad(radiance, (7, 7, 7, 7)), torch.Generator().manual_seed(0))
    network = ReconstructionNet(preset("fast"))
    optimizer = torch.optim.Adam(network.parameters(), lr=1e-3)
    losses = []
    for _ in range(25):
        loss = reconstruction_loss(network(ldr), radiance, LossWeights(), None)["total"]
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        losses.append(float(loss.detach()))
    assert losses[-1] < 0.6 * losses[0]


def test_the_optics_gradient_trains_the_rank1_doe():
    """Energy regulariser alone: from a plate that scatters far too much (its V, Q doubled: ~1 rad RMS phase),
    the height map moves and the centre energy approaches its target."""
    capture = OpticalCapture(load_profile("simulated"), doe="rank1", seed=0)
    target = capture.energy_target
    heightmap = capture.simulator.heightmap
    with torch.no_grad():
        heightmap.v.mul_(2.0)
        heightmap.q.mul_(2.0)
    initial_heights = heightmap().detach().clone()
    _, fraction = capture.psf()
    initial_gap = float((fraction.detach() - target).abs().mean())
    optimizer = torch.optim.Adam(heightmap.parameters(), lr=2e-2)
    for _ in range(15):
        _, fraction = capture.psf()
        loss = energy_regulariser(fraction, target)
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
    _, fraction = capture.psf()
    final_gap = float((fraction.detach() - target).abs().mean())
    moved_m = float((heightmap().detach() - initial_heights).abs().max())
    assert initial_gap > 0.2 and final_gap < initial_gap / 3
    assert moved_m > 1e-8  # more than 1 % of h_max


def test_the_energy_target_is_94_percent_of_what_the_bare_lens_keeps_central():
    """The f/9.8 simulated lens loses 4-6 % outside the 7 x 7 centre to its Airy rings (most in red, whose rings
    are widest): the DOE is asked to spread 6 % of what the bare lens keeps there, not to fight diffraction."""
    capture = OpticalCapture(load_profile("simulated"), doe="rank1", seed=0)
    bare = capture.simulator(heights_m=torch.zeros_like(capture.simulator.heightmap())).centre_energy_fraction
    torch.testing.assert_close(capture.energy_target, 0.94 * bare)
    assert 0.93 < float(bare.min()) and float(bare.max()) < 0.975
    assert float(bare[0]) < float(bare[1]) < float(bare[2])  # Airy radius grows with wavelength
    assert OpticalCapture(load_profile("simulated"), psf=dirac(15)).energy_target is None


def test_reconstruction_loss_reaches_the_height_map():
    capture = OpticalCapture(load_profile("simulated"), doe="rank1", seed=0)
    network = ReconstructionNet(preset("fast"))
    margin = capture.margin_px
    radiance = torch.rand(1, 3, 32 + 2 * margin, 32 + 2 * margin)
    radiance[..., 40:44, 40:44] = 100.0
    ldr, _ = capture(radiance, torch.Generator().manual_seed(0))
    target = radiance[..., margin:margin + 32, margin:margin + 32]
    reconstruction_loss(network(ldr), target, LossWeights(), None)["total"].backward()
    v, q = capture.simulator.heightmap.v, capture.simulator.heightmap.q
    assert float(v.grad.abs().sum()) > 0 and float(q.grad.abs().sum()) > 0
    assert torch.isfinite(v.grad).all() and torch.isfinite(q.grad).all()


def _tiny(**changes) -> TrainConfig:
    values = dict(steps=4, batch=1, crop_px=32, checkpoint_every=2, doe="rank1")
    values.update(changes)
    return TrainConfig(**values)


def test_resume_continues_exactly_where_an_interrupted_run_would_be(tmp_path):
    straight = train(_tiny(), tmp_path / "straight", quiet=True)
    train(_tiny(), tmp_path / "resumed", quiet=True, stop_after=3)  # interrupted after step 3
    assert not (tmp_path / "resumed" / "model.pt").exists()
    resumed = train(_tiny(), tmp_path / "resumed", resume=True, quiet=True, data_workers=2)
    for key in ("total", "fusion", "energy"):
        assert resumed[key] == pytest.approx(straight[key], rel=1e-5)
    a, b = read_checkpoint(tmp_path / "straight" / "model.pt"), read_checkpoint(tmp_path / "resumed" / "model.pt")
    assert all(torch.allclose(a["network"][k], b["network"][k], atol=1e-6) for k in a["network"])
    assert torch.allclose(a["doe"]["heights_m"], b["doe"]["heights_m"], atol=1e-12)
    log = [json.loads(line) for line in (tmp_path / "resumed" / "log.jsonl").read_text().splitlines()]
    assert [entry["step"] for entry in log] == [1, 2, 3, 4]
    for name in ("psf.exr", "psf.png", "loss.png", "heightmap.exr", "config.json"):
        assert (tmp_path / "resumed" / name).is_file()
    with pytest.raises(InputError, match="already holds a run"):
        train(_tiny(), tmp_path / "straight", quiet=True)
    with pytest.raises(InputError, match="does not exist"):
        train(_tiny(), tmp_path / "nothing", resume=True, quiet=True)
    with pytest.raises(InputError, match=r"--steps 3: .* is a run of 4 steps; on --resume --steps may only grow"):
        train(_tiny(steps=3), tmp_path / "straight", resume=True, quiet=True)  # was silently trained to 4


def test_fixed_psf_runs_train_only_the_network_and_load_back(tmp_path):
    train(_tiny(doe=None, psf="dual-peak", steps=2), tmp_path / "run", quiet=True)
    model = load_model(tmp_path / "run" / "model.pt")
    assert np.allclose(model.psf, fixed_psf("dual-peak", load_profile("simulated")))
    assert read_checkpoint(tmp_path / "run" / "model.pt")["doe"] is None
    assert model.preset == "fast" and model.step == 2 and not model.network.training
    from hdrcam.optics.psf_file import load_psf

    pitch_m = load_profile("simulated").camera.pixel_pitch_m
    np.testing.assert_allclose(load_psf(tmp_path / "run" / "psf.exr", pixel_pitch_m=pitch_m), model.psf, atol=1e-7)
    with pytest.raises(InputError, match="pixel"):  # psf.exr had no pitch: any camera's check passed
        load_psf(tmp_path / "run" / "psf.exr", pixel_pitch_m=pitch_m * 0.66)


def test_damaged_checkpoints_are_one_line_errors(tmp_path):
    (tmp_path / "junk.pt").write_bytes(b"\x00" * 100)
    with pytest.raises(InputError, match="not a readable checkpoint"):
        read_checkpoint(tmp_path / "junk.pt")
    torch.save({"format": "something else"}, tmp_path / "foreign.pt")
    with pytest.raises(InputError, match="not an hdrcam checkpoint"):
        read_checkpoint(tmp_path / "foreign.pt")
    with pytest.raises(InputError, match="does not exist"):
        read_checkpoint(tmp_path / "missing.pt")
    torch.jit.save(torch.jit.script(torch.nn.Linear(2, 2)), tmp_path / "exported.pt")
    with pytest.raises(InputError, match="exported.pt: a TorchScript export .*, not an hdrcam checkpoint"):
        read_checkpoint(tmp_path / "exported.pt")


def test_a_run_saved_before_the_precision_options_resumes_with_their_defaults(tmp_path):
    train(_tiny(steps=2), tmp_path / "run", quiet=True, stop_after=1)
    checkpoint = tmp_path / "run" / "checkpoint.pt"
    state = read_checkpoint(checkpoint)
    for key in ("precision", "channels_last"):
        del state["config"][key]
    torch.save(state, checkpoint)
    assert train(_tiny(steps=2), tmp_path / "run", resume=True, quiet=True)["step"] == 2


def test_bfloat16_autocast_and_channels_last_train_the_network_in_float32_losses(tmp_path):
    reference = train(_tiny(steps=2, doe=None, psf="dirac"), tmp_path / "fp32", quiet=True)
    mixed = train(_tiny(steps=2, doe=None, psf="dirac", precision="bfloat16", channels_last=True),
                  tmp_path / "bf16", quiet=True)
    assert np.isfinite(mixed["total"])
    assert mixed["total"] == pytest.approx(reference["total"], rel=0.05)  # same batches, bf16 rounding only
    assert load_model(tmp_path / "bf16" / "model.pt").network.splitting is not None


def test_float16_needs_cuda_and_unknown_precisions_are_refused(tmp_path):
    with pytest.raises(InputError, match="needs a CUDA device"):
        train(_tiny(precision="float16"), tmp_path / "run", quiet=True, device=torch.device("cpu"))
    with pytest.raises(InputError, match="precision must be one of"):
        _tiny(precision="float8")


def test_a_restart_interrupted_before_it_claims_the_folder_keeps_the_runs_options(tmp_path, monkeypatch):
    from hdrcam.cli import main
    from hdrcam.train import design

    run, steps = tmp_path / "run", design._train_steps

    def interrupted(*arguments):
        raise KeyboardInterrupt

    monkeypatch.setattr(design, "_train_steps", interrupted)  # config.json written, no checkpoint yet
    tiny = ["--steps", "2", "--crop", "32", "--batch", "1", "--psf", "dirac", "--device", "cpu"]
    assert main(["design", *tiny, "--seed", "7", "--lr", "3e-4", "--out", str(run)]) == 130
    monkeypatch.setattr(design, "_train_steps", steps)
    monkeypatch.setattr(design.SceneSource, "check_training_folders", interrupted)  # before the new claim
    assert main(["design", "--resume", "--out", str(run)]) == 130
    assert json.loads((run / "config.json").read_text())["seed"] == 7  # it was deleted first: the options lost
    monkeypatch.undo()
    assert main(["design", "--resume", "--seed", "4", "--out", str(run)]) == 1  # it restarted as seed 4
    assert main(["design", "--resume", "--out", str(run)]) == 0
    config = read_checkpoint(run / "model.pt")["config"]
    assert (config["seed"], config["learning_rate"], config["steps"]) == (7, 3e-4, 2)


def test_a_run_resumes_from_another_folder_and_after_its_files_moved(tmp_path, monkeypatch, capsys):
    import shutil
    from pathlib import Path

    from hdrcam.cli import main

    measured = Path(__file__).resolve().parents[2] / "calibration" / "simulated-rank1" / "psf.exr"
    for folder in ("a", "b", "c"):
        (tmp_path / folder).mkdir()
    shutil.copyfile(measured, tmp_path / "a" / "psf.exr")
    monkeypatch.chdir(tmp_path / "a")
    run, tiny = tmp_path / "run", ["--steps", "2", "--crop", "32", "--batch", "1", "--device", "cpu"]
    _design_stopped_after_a_checkpoint(monkeypatch, ["design", "--psf", "psf.exr", *tiny, "--out", str(run)])
    moved, gone, other, smaller = tmp_path / "moved", tmp_path / "gone", tmp_path / "other", tmp_path / "smaller"
    for copy in (moved, gone, other, smaller):
        shutil.copytree(run, copy)
    monkeypatch.chdir(tmp_path / "b")  # the PSF spelled from another folder is the same file
    assert main(["design", "--resume", "--psf", "../a/psf.exr", "--out", str(run)]) == 0  # was: another psf
    (tmp_path / "a" / "psf.exr").rename(tmp_path / "c" / "psf.exr")
    assert main(["design", "--resume", "--psf", "../c/psf.exr", "--out", str(moved)]) == 0  # the same bytes
    resumed, moved_run = read_checkpoint(run / "model.pt")["network"], read_checkpoint(moved / "model.pt")["network"]
    assert all(torch.equal(resumed[key], moved_run[key]) for key in resumed)  # both continued the same run
    (tmp_path / "c" / "psf.exr").unlink()
    assert main(["design", "--resume", "--out", str(gone)]) == 0  # the checkpoint's PSF stands in for the file
    assert all(torch.equal(resumed[key], read_checkpoint(gone / "model.pt")["network"][key]) for key in resumed)
    flipped = read_exr(measured)
    write_exr(tmp_path / "c" / "flipped.exr", flipped.rgb()[::-1].copy(), channel_names=("R", "G", "B"),
              attributes={key: value for key, value in flipped.attributes.items() if key == "pixel_pitch_m"})
    capsys.readouterr()
    assert main(["design", "--resume", "--psf", "../c/flipped.exr", "--out", str(other)]) == 1  # another PSF
    assert "not the PSF other trained behind so far (its own file is gone)" in capsys.readouterr().err
    write_exr(tmp_path / "c" / "smaller.exr", flipped.rgb()[2:-2, 2:-2].copy(), channel_names=("R", "G", "B"),
              attributes={key: value for key, value in flipped.attributes.items() if key == "pixel_pitch_m"})
    assert main(["design", "--resume", "--psf", "../c/smaller.exr", "--out", str(smaller)]) == 1  # was exit 3
    assert "not the PSF smaller trained behind" in capsys.readouterr().err


def test_a_run_that_saved_no_step_takes_a_psf_file_given_where_its_own_is_gone(tmp_path, monkeypatch):
    import shutil
    from pathlib import Path

    from hdrcam.cli import main
    from hdrcam.train import design

    measured = Path(__file__).resolve().parents[2] / "calibration" / "simulated-rank1" / "psf.exr"
    shutil.copyfile(measured, tmp_path / "first.exr")
    steps = design._train_steps

    def interrupted(*arguments):
        raise KeyboardInterrupt

    monkeypatch.setattr(design, "_train_steps", interrupted)  # config.json written, no checkpoint
    run, tiny = tmp_path / "run", ["--steps", "1", "--crop", "32", "--batch", "1", "--device", "cpu"]
    assert main(["design", "--psf", str(tmp_path / "first.exr"), *tiny, "--out", str(run)]) == 130
    monkeypatch.setattr(design, "_train_steps", steps)
    (tmp_path / "first.exr").rename(tmp_path / "second.exr")
    assert main(["design", "--resume", "--psf", str(tmp_path / "second.exr"), "--out", str(run)]) == 0
    assert read_checkpoint(run / "model.pt")["config"]["psf"] == str(tmp_path / "second.exr")


def test_a_run_on_a_relative_data_folder_resumes_from_another_folder(tmp_path, monkeypatch):
    from hdrcam.cli import main

    scenes = tmp_path / "a" / "scenes"
    scenes.mkdir(parents=True)
    photo = np.random.default_rng(0).uniform(0.0, 1.0, (96, 96, 3)).astype(np.float32)
    photo[40:44, 40:44] = 50.0
    write_exr(scenes / "photo.exr", photo)
    (tmp_path / "b").mkdir()
    monkeypatch.chdir(tmp_path / "a")
    run = tmp_path / "run"
    tiny = ["--steps", "2", "--crop", "32", "--batch", "1", "--device", "cpu", "--psf", "dirac"]
    _design_stopped_after_a_checkpoint(monkeypatch, ["design", "--data", "scenes", *tiny, "--out", str(run)])
    monkeypatch.chdir(tmp_path / "b")  # 'scenes is not a folder', then '--data ../a/scenes' refused as other data
    assert main(["design", "--resume", "--data", "../a/scenes", "--out", str(run)]) == 0
    assert read_checkpoint(run / "model.pt")["config"]["data"] == str(scenes)


def _design_stopped_after_a_checkpoint(monkeypatch, argv: list[str]) -> None:
    """Run ``hdrcam`` with ``argv`` (a design) interrupted, as SIGINT would, right after its first checkpoint."""
    from hdrcam.cli import main
    from hdrcam.train import design

    train_slice = design.train

    def stopped(config, folder, **options):
        train_slice(config, folder, **options, stop_after=1)
        raise KeyboardInterrupt

    with monkeypatch.context() as patch:
        patch.setattr(design, "train", stopped)
        assert main(argv) == 130


def test_a_checkpoint_saved_without_its_config_still_loads(tmp_path):
    from hdrcam.train.checkpoint import SHIPPED_CHECKPOINT, save_checkpoint

    state = read_checkpoint(SHIPPED_CHECKPOINT)
    del state["config"]
    save_checkpoint(tmp_path / "bare.pt", state)
    assert load_model(tmp_path / "bare.pt").fixed_psf is None  # KeyError: 'config', exit 3


def test_an_init_checkpoint_whose_weights_do_not_match_the_network_is_refused(tmp_path):
    """finetune --checkpoint and design --init loaded with strict=False: a checkpoint of another hdrcam version
    (88 highlight layers renamed) trained those layers from random weights, exit 0, where reconstruct refuses it."""
    from hdrcam.train.checkpoint import SHIPPED_CHECKPOINT, save_checkpoint
    from hdrcam.train.design import build_model

    state = read_checkpoint(SHIPPED_CHECKPOINT)
    state["network"] = {("old_" + key if key.startswith("highlight.") else key): value
                        for key, value in state["network"].items()}
    state.pop("format", None)
    save_checkpoint(tmp_path / "renamed.pt", state)
    with pytest.raises(InputError, match=r"renamed.pt: network weights do not match preset 'fast' \(\d+ missing"):
        build_model(_tiny(doe=None, psf="dirac", init_checkpoint=str(tmp_path / "renamed.pt")), None, True)
    state = read_checkpoint(SHIPPED_CHECKPOINT)  # one layer of another width: load_state_dict's multi-line error
    weight = state["network"]["splitting.entry.0.weight"]
    state["network"]["splitting.entry.0.weight"] = torch.cat([weight, weight[:1]])
    state.pop("format", None)
    save_checkpoint(tmp_path / "wider.pt", state)
    with pytest.raises(InputError, match=r"wider.pt: .* 1 of another size"):
        build_model(_tiny(doe=None, psf="dirac", init_checkpoint=str(tmp_path / "wider.pt")), None, True)


def test_building_a_run_leaves_the_callers_random_state_and_still_follows_the_runs_seed():
    """design / finetune reseeded the caller's global torch RNG with the run's seed (a notebook's own stream
    changed under it)."""
    from hdrcam.train.design import build_model

    torch.manual_seed(1234)
    expected = torch.rand(3)
    torch.manual_seed(1234)
    first = build_model(_tiny(doe=None, psf="dirac", seed=5), None, True)
    assert torch.equal(torch.rand(3), expected)
    second = build_model(_tiny(doe=None, psf="dirac", seed=5), None, True)
    for name, value in first.network.state_dict().items():
        assert torch.equal(value, second.network.state_dict()[name]), name
