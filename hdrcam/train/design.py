"""The training loop of ``hdrcam design`` (DOE + network end to end) and ``hdrcam finetune`` (network only).

Each step draws a batch of exposure-scaled scenes, captures them through the simulated optics and sensor
(:mod:`hdrcam.train.optical_capture`), reconstructs, and minimises Eq. 10 plus, when the DOE is trained,
the energy regulariser (94 % of the energy the bare lens keeps in the PSF centre;
:func:`hdrcam.train.optical_capture.bare_lens`). Adam with polynomial decay.

A run folder holds: config.json, log.jsonl (one line per step), checkpoint.pt (resumable, every
``checkpoint_every`` steps and at the end), model.pt (the final network and PSF, no optimiser state),
psf.exr, psf.png, loss.png and, for a trained DOE, heightmap.exr. ``resume`` continues from checkpoint.pt
with the saved noise state; each step's scenes are drawn from that step's own seed (hdrcam.train.batches), so
an interrupted run ends where an uninterrupted one would.

Speed on a GPU: scenes are drawn on ``data_workers`` CPU threads ahead of the step (hdrcam.train.batches);
``precision`` bfloat16 / float16 runs the network's forward under autocast (float16 with loss scaling, CUDA
only) while the optics, the sensor and the losses stay float32; ``channels_last`` stores the network's weights
and input NHWC.

Launched by ``torchrun --nproc_per_node K``, every process trains on its own batches and
DistributedDataParallel averages the gradients (network and height map); only rank 0 writes.
"""

from __future__ import annotations

import dataclasses
import json
import os
import time
from pathlib import Path

import numpy as np
import torch
import torch.distributed as dist
from torch import nn
from tqdm import tqdm

from hdrcam.data.scenes import SceneSource, absolute_mixture
from hdrcam.errors import InputError
from hdrcam.limits import check_memory
from hdrcam.io.atomic import check_destination_folder, write_text_atomic
from hdrcam.io.exr import write_exr
from hdrcam.io.png import write_png
from hdrcam.optics.energy import energy_regulariser
from hdrcam.optics.heightmap import save_heightmap
from hdrcam.optics.psf_file import PSF_UNITS
from hdrcam.preview import line_plot, log_psf_rgb, radial_profile_plot, side_by_side
from hdrcam.profiles import load_profile
from hdrcam.recon.losses import reconstruction_loss
from hdrcam.recon.network import Reconstruction, ReconstructionNet
from hdrcam.recon.presets import preset as preset_named
from hdrcam.recon.vgg import vgg_for_preset
from hdrcam.train.batches import BatchStream
from hdrcam.train.checkpoint import load_network_weights, read_checkpoint, recorded_checkpoint, save_checkpoint
from hdrcam.train.choices import FIXED_PSFS
from hdrcam.train.run_options import moved_file, same_file
from hdrcam.train.config import TrainConfig, read_run_config
from hdrcam.train.optical_capture import OpticalCapture, fixed_psf


class DesignModel(nn.Module):
    """Optics + network as one module, so DistributedDataParallel sees every trained parameter."""

    def __init__(self, capture: OpticalCapture, network: ReconstructionNet, *, precision: str = "float32",
                 channels_last: bool = False):
        super().__init__()
        if channels_last:
            network = network.to(memory_format=torch.channels_last)
        self.capture, self.network = capture, network
        self.autocast_dtype = None if precision == "float32" else getattr(torch, precision)
        self.memory_format = torch.channels_last if channels_last else torch.contiguous_format

    def forward(self, radiance: torch.Tensor, generator: torch.Generator):
        ldr, centre_fraction = self.capture(radiance, generator)  # float32: the optics need its precision
        with torch.autocast(ldr.device.type, dtype=self.autocast_dtype, enabled=self.autocast_dtype is not None):
            output = self.network(ldr.contiguous(memory_format=self.memory_format))
        if self.autocast_dtype is not None:  # the losses (log, sqrt, Huber of values up to 2^8) in float32
            output = Reconstruction(*(getattr(output, field.name).float() for field in dataclasses.fields(output)))
        return output, centre_fraction, ldr


def build_model(config: TrainConfig, vgg_weights: Path | None, random_vgg: bool, saved: dict | None = None
                ) -> DesignModel:
    """The run's optics and network; ``saved``: the checkpoint it resumes from, whose weights replace the
    initial ones (the init checkpoint is not read: it may have moved) and whose PSF stands in for a PSF file
    that is no longer where the run found it (a run folder copied to another machine)."""
    profile = load_profile(config.profile)
    preset = preset_named(config.preset)
    vgg = vgg_for_preset(preset, vgg_weights, random_features=random_vgg)
    if config.psf is not None:
        moved = saved is not None and config.psf not in FIXED_PSFS and not Path(config.psf).is_file()
        psf = saved["psf"].numpy() if moved else fixed_psf(config.psf, profile)
        capture = OpticalCapture(profile, psf=psf, windshield=config.psf == "windshield")
    else:
        capture = OpticalCapture(profile, doe=config.doe, seed=config.seed)
    with torch.random.fork_rng(devices=[]):  # the caller's random state is left as it was (the weights are made
        torch.random.default_generator.manual_seed(config.seed)  # on the CPU; manual_seed would reseed CUDA's too)
        network = ReconstructionNet(preset, vgg)
    if config.init_checkpoint and saved is None:
        state = read_checkpoint(recorded_checkpoint(config.init_checkpoint))
        if state["preset"] != preset.name:
            raise InputError(f"{config.init_checkpoint} holds a {state['preset']!r} network, not {preset.name!r}")
        load_network_weights(network, state["network"], config.init_checkpoint)
    if config.init_doe_checkpoint and saved is None:
        _start_doe(capture.simulator.heightmap, config)
    return DesignModel(capture, network, precision=config.precision, channels_last=config.channels_last)


def _start_doe(heightmap: torch.nn.Module, config: TrainConfig) -> None:
    """The trained DOE's parameters (rank-1 factors V, Q of Eq. 3, or free-form W) from the DOE saved in
    ``config.init_doe_checkpoint``: the same kind on the same feature grid, else a one-line InputError."""
    source = config.init_doe_checkpoint
    try:
        state = read_checkpoint(recorded_checkpoint(source))
    except InputError as error:  # damaged, foreign or missing: say which option named it
        raise InputError(f"--init-doe: {error}") from None
    doe = state.get("doe")
    if doe is None:
        raise InputError(f"--init-doe {source}: holds no trained DOE (a network trained behind a fixed PSF)")
    if doe["kind"] != config.doe:
        raise InputError(f"--init-doe {source}: holds a {doe['kind']} DOE, this run trains a {config.doe} one")
    wanted = {name: tuple(value.shape) for name, value in heightmap.state_dict().items()}
    found = {name: tuple(value.shape) for name, value in doe["parameters"].items()}
    if wanted != found:
        raise InputError(f"--init-doe {source}: its DOE's parameters {found} (profile {state['profile']}) do not fit "
                         f"this run's {wanted} (profile {config.profile})")
    heightmap.load_state_dict(doe["parameters"])


def _distributed() -> tuple[int, int]:
    world = int(os.environ.get("WORLD_SIZE", "1"))
    if world > 1 and not dist.is_initialized():
        dist.init_process_group("nccl" if torch.cuda.is_available() else "gloo")
    return (dist.get_rank(), world) if world > 1 else (0, 1)


TRAIN_BYTES_PER_PIXEL = 8192  # a training step per crop pixel (measured, fast preset: 4.3 kB, x 2)
RUN_FILES = ("config.json", "log.jsonl", "checkpoint.pt", "model.pt", "psf.exr", "psf.png", "loss.png",
             "heightmap.exr")


def train(config: TrainConfig, out: Path, *, resume: bool = False, vgg_weights: Path | None = None,
          random_vgg: bool = False, device: torch.device | None = None, quiet: bool = False,
          stop_after: int | None = None, data_workers: int | None = None, restart: bool = False) -> dict:
    """Run (or continue) a training run in ``out``; returns the last logged step.

    ``restart``: ``out`` holds a run stopped before its first checkpoint (its config.json, perhaps a log): it
    starts again from step 0 there, config.json replaced only once the new run claims the folder (an interrupt
    before that leaves the old one, so --resume still knows the run's options).

    ``stop_after`` N: checkpoint and return after N steps of this call (training in time slices; continue
    with ``resume``). ``data_workers``: CPU threads drawing scenes ahead of the step (the results do not
    depend on it; default: none on a CPU, whose cores the step uses - each batch is drawn when the step asks -
    else one per scene of a batch, leaving a core free).
    """
    out = Path(out)
    rank, world = _distributed()
    device = device or torch.device(f"cuda:{rank % max(torch.cuda.device_count(), 1)}"
                                    if torch.cuda.is_available() else "cpu")
    if config.crop_px % 16 or config.crop_px < 32:
        raise InputError(f"--crop must be a multiple of 16 and at least 32 (the U-Net halves it four times and "
                         f"normalises what is left), got {config.crop_px}")
    check_memory(f"--batch {config.batch} of --crop {config.crop_px}",
                 config.batch * config.crop_px ** 2 * TRAIN_BYTES_PER_PIXEL, "use a smaller --batch or --crop")
    checkpoint_path = out / "checkpoint.pt"
    if not resume and not restart and any((out / name).exists() for name in RUN_FILES):
        raise InputError(f"{out} already holds a run; pass --resume to continue it or choose another --out")
    if config.precision == "float16" and device.type != "cuda":
        raise InputError("--precision float16 needs a CUDA device (loss scaling); use bfloat16 or float32")
    if resume and not checkpoint_path.exists():
        raise InputError(f"--resume: {checkpoint_path} does not exist")
    check_destination_folder(out)  # before the model is built: an unusable --out fails at once
    if restart:  # the options it started with, as a resume from a checkpoint checks them (steps may change:
        # no step was saved, so no learning-rate schedule has begun; nor a PSF, so a PSF file may replace a gone one)
        _check_same_run(out / "config.json", read_run_config(out / "config.json"), config,
                        psf_file_may_replace=True)
    saved = read_checkpoint(checkpoint_path) if resume else None
    if saved is not None:
        steps = config.steps
        _check_same_run(checkpoint_path, saved["config"], config, saved_psf=saved["psf"])
        config = TrainConfig.from_dict(saved["config"], checkpoint_path)
        if steps < config.steps:  # the learning-rate schedule decays over the run's steps: it may only grow
            raise InputError(f"--steps {steps}: {out} is a run of {config.steps} steps; on --resume --steps may only "
                             "grow it")
        config.steps = steps

    source = SceneSource(config.data)
    model = build_model(config, vgg_weights, random_vgg, saved).to(device)
    source.check_training_folders(config.crop_px + 2 * model.capture.margin_px)
    optimizer = torch.optim.Adam([
        {"params": [p for p in model.network.parameters() if p.requires_grad], "lr": config.learning_rate,
         "base_lr": config.learning_rate},
        {"params": list(model.capture.parameters()), "lr": config.doe_learning_rate,
         "base_lr": config.doe_learning_rate}])
    noise = torch.Generator(device=device).manual_seed(config.seed * 1000 + rank)
    start = 0
    if saved is not None:
        if model.capture.simulator is None and not _same_psf(model.capture.fixed.detach().cpu(), saved["psf"]):
            raise InputError(f"--psf {config.psf}: not the PSF {out.name} trained behind so far (the file changed "
                             "since); resume needs the same PSF")
        load_network_weights(model.network, saved["network"], out / "checkpoint.pt")
        if saved["doe"] is not None:
            model.capture.simulator.heightmap.load_state_dict(saved["doe"]["parameters"])
        optimizer.load_state_dict(saved["optimizer"])
        noise.set_state(saved["noise_generator"])
        start = int(saved["step"])
    trained = _maybe_distributed(model, world, device)
    scaler = torch.amp.GradScaler(device.type, enabled=config.precision == "float16")
    if rank == 0:
        out.mkdir(parents=True, exist_ok=True)
        # a new run claims the folder with config.json (published without replacing: a second run started
        # into it at the same time fails here); the run's later files are its own
        write_text_atomic(out / "config.json", json.dumps(config.as_dict(), indent=2) + "\n",
                          overwrite=resume or restart)
        log_lines = _log_lines(out / "log.jsonl", start)
    progress = tqdm(total=min(config.steps, start + (stop_after or config.steps)) - start, desc=f"design {out.name}",
                    unit="step") if rank == 0 and not quiet else None
    end = config.steps if stop_after is None else min(config.steps, start + stop_after)
    model.train()
    if data_workers is None:
        data_workers = 0 if device.type == "cpu" else max(1, min(config.batch, (os.cpu_count() or 2) - 1))
    batches = BatchStream(source, crop_px=config.crop_px, margin_px=model.capture.margin_px, batch=config.batch,
                          run_seed=config.seed, rank=rank, start=start, workers=data_workers)
    with batches:
        last = _train_steps(config, out, model, trained, optimizer, scaler, batches, noise, range(start, end),
                            rank, progress, log_lines if rank == 0 else None, device)
    if progress:
        progress.close()
    if rank == 0:
        _save_run(out, model, config, optimizer, noise, end, log_lines)
        if end == config.steps:
            _write_results(out, model, config, log_lines)
    return last


def _train_steps(config: TrainConfig, out: Path, model: DesignModel, trained: nn.Module, optimizer, scaler,
                 batches: BatchStream, noise: torch.Generator, steps: range, rank: int, progress,
                 log_lines: list[str] | None, device: torch.device) -> dict:
    """The optimiser steps ``steps``; checkpoints every ``checkpoint_every`` (rank 0); the last step's log."""
    margin, last = model.capture.margin_px, {}
    for step in steps:
        began = time.perf_counter()
        for group in optimizer.param_groups:
            group["lr"] = config.learning_rate_at(step, group["base_lr"])
        radiance = torch.from_numpy(batches.next_batch()).permute(0, 3, 1, 2).to(device, non_blocking=True)
        target = radiance[..., margin:margin + config.crop_px, margin:margin + config.crop_px]
        output, centre_fraction, ldr = trained(radiance, noise)
        terms = reconstruction_loss(output, target, config.weights, model.network.splitting.vgg, ldr.detach())
        if centre_fraction is not None:
            terms["energy"] = config.weights.energy * energy_regulariser(centre_fraction, model.capture.energy_target)
            terms["total"] = terms["total"] + terms["energy"]
        optimizer.zero_grad(set_to_none=True)
        scaler.scale(terms["total"]).backward()
        scaler.step(optimizer)
        scaler.update()
        if not all(torch.isfinite(value) for value in terms.values()):
            raise InputError(f"training diverged at step {step + 1} (loss is not finite); lower --lr")
        last = {"step": step + 1, **{k: round(float(v.detach()), 6) for k, v in terms.items()},
                "lr": config.learning_rate_at(step, config.learning_rate),
                "seconds": round(time.perf_counter() - began, 4)}
        if centre_fraction is not None:
            last["centre_energy"] = [round(float(v), 5) for v in centre_fraction.detach()]
        if rank == 0:
            log_lines.append(json.dumps(last))
            if progress:
                progress.set_postfix_str(f"loss {last['total']:.4f}", refresh=False)
                progress.update()
            if (step + 1) % config.checkpoint_every == 0 and step + 1 < steps.stop:
                _save_run(out, model, config, optimizer, noise, step + 1, log_lines)
    return last


FILE_OPTIONS = ("psf", "init_checkpoint", "init_doe_checkpoint", "profile")  # run options that may name a file


def _check_same_run(checkpoint_path: Path, saved: dict, config: TrainConfig, *,
                    saved_psf: torch.Tensor | None = None, psf_file_may_replace: bool = False) -> None:
    """Refuse to resume a run with other settings (seed, PSF, learning rate, ...): only ``steps`` may grow. A file
    is the same however its path is spelled (relative to another folder, absolute) and wherever a byte-identical
    copy lies; a PSF file given where the run's own is gone, when it holds the checkpoint's ``saved_psf`` or
    (``psf_file_may_replace``: a run that saved no step) whatever it holds."""
    wanted, saved = config.as_dict(), TrainConfig.from_dict(saved, checkpoint_path).as_dict()
    for key in sorted((set(saved) | set(wanted)) - {"steps"}):
        if key in FILE_OPTIONS and same_file(saved.get(key), wanted.get(key)):
            continue
        if key == "data" and absolute_mixture(saved[key]) == absolute_mixture(wanted[key]):
            continue  # the same folders, spelled from another folder
        if key == "psf" and moved_file(saved.get(key), wanted.get(key), FIXED_PSFS):
            if saved_psf is not None:
                given = torch.from_numpy(fixed_psf(wanted[key], load_profile(wanted["profile"])))
                if not _same_psf(given, saved_psf):
                    raise InputError(f"--psf {wanted[key]}: not the PSF {checkpoint_path.parent.name} trained behind "
                                     "so far (its own file is gone); resume needs the same PSF")
                continue
            if psf_file_may_replace:
                continue
        if saved.get(key) != wanted.get(key):
            raise InputError(f"--resume: {checkpoint_path} was started with {key} {saved.get(key)!r}, this run asks "
                             f"for {wanted.get(key)!r}; resume with the run's own options, or choose another --out")


def _same_psf(psf: torch.Tensor, saved_psf: torch.Tensor) -> bool:
    """Whether a (3, S, S) PSF is the one a run saved: same size, values within float32 rounding."""
    return psf.shape == saved_psf.shape and torch.allclose(psf.float(), saved_psf.float(), rtol=1e-5, atol=1e-8)


def _maybe_distributed(model: nn.Module, world: int, device: torch.device) -> nn.Module:
    """The model itself on one process; wrapped in DistributedDataParallel under torchrun."""
    if world == 1:
        return model
    return nn.parallel.DistributedDataParallel(model, device_ids=[device.index] if device.type == "cuda" else None)


def _log_lines(path: Path, start: int) -> list[str]:
    """The log's lines up to step ``start`` (later ones belong to a run that was interrupted)."""
    if not path.exists():
        return []
    kept = []
    for number, line in enumerate(path.read_text().splitlines(), 1):
        try:
            step = json.loads(line)["step"] if line else None
        except (json.JSONDecodeError, TypeError, KeyError):
            raise InputError(f"{path}: line {number} is damaged (not a logged step); restore the run folder "
                             "or start a new run") from None
        if step is not None and step <= start:
            kept.append(line)
    return kept


def checkpoint_state(model: DesignModel, config: TrainConfig, step: int) -> dict:
    """What a checkpoint holds besides the optimiser and random states."""
    with torch.no_grad():
        psf, _ = model.capture.psf()
    doe = None
    if model.capture.simulator is not None:
        heightmap = model.capture.simulator.heightmap
        with torch.no_grad():
            heights = heightmap().detach().cpu()
        doe = {"kind": config.doe, "feature_pitch_m": heightmap.feature_pitch_m, "heights_m": heights,
               "parameters": {k: v.detach().cpu() for k, v in heightmap.state_dict().items()}}
    return {"preset": config.preset, "profile": config.profile, "step": step, "config": config.as_dict(),
            "psf": psf.detach().cpu().float().contiguous(), "network": model.network.trainable_state(), "doe": doe}


def _save_run(out: Path, model: DesignModel, config: TrainConfig, optimizer, noise, step: int,
              log_lines: list[str]) -> None:
    write_text_atomic(out / "log.jsonl", "".join(line + "\n" for line in log_lines), overwrite=True)
    state = checkpoint_state(model, config, step)
    save_checkpoint(out / "checkpoint.pt", {**state, "optimizer": optimizer.state_dict(),
                                            "noise_generator": noise.get_state()})


def _write_results(out: Path, model: DesignModel, config: TrainConfig, log_lines: list[str]) -> None:
    state = checkpoint_state(model, config, config.steps)
    save_checkpoint(out / "model.pt", state)
    psf = state["psf"].numpy()
    write_exr(out / "psf.exr", psf.transpose(1, 2, 0), channel_names=("R", "G", "B"), overwrite=True,
              attributes={"pixel_pitch_m": load_profile(config.profile).camera.pixel_pitch_m, "units": PSF_UNITS})
    write_png(out / "psf.png", side_by_side([log_psf_rgb(psf), radial_profile_plot(psf)], height_px=384),
              overwrite=True)
    if state["doe"] is not None:
        save_heightmap(out / "heightmap.exr", state["doe"]["heights_m"].numpy(), state["doe"]["feature_pitch_m"],
                       overwrite=True)
    records = [json.loads(line) for line in log_lines]
    if records:
        steps = np.array([r["step"] for r in records])
        series = {name: (steps, _smoothed(np.array([r[name] for r in records])))
                  for name in ("total", "unsaturated", "highlight", "fusion", "exclusion", "energy")
                  if name in records[0]}
        write_png(out / "loss.png", line_plot(series, f"{out.name}: training loss (smoothed)"), overwrite=True)


def _smoothed(values: np.ndarray, window: int = 25) -> np.ndarray:
    """Trailing mean over up to ``window`` steps (shorter at the start; no edge artefacts)."""
    totals = np.cumsum(np.concatenate([[0.0], values]))
    ends = np.arange(1, len(values) + 1)
    starts = np.maximum(ends - window, 0)
    return (totals[ends] - totals[starts]) / (ends - starts)
