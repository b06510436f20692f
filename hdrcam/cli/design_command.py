"""``hdrcam design`` and ``hdrcam finetune``: train a DOE and network end to end, or a network on a fixed PSF."""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path
from typing import TYPE_CHECKING

from hdrcam.cli.arguments import compute_device, positive_float, positive_int
from hdrcam.errors import InputError
from hdrcam.recon.presets import PRESETS
from hdrcam.train.choices import FIXED_PSFS, TRAINABLE_DOES

if TYPE_CHECKING:
    from hdrcam.train.config import TrainConfig


def _training_options(parser: argparse.ArgumentParser, default_steps: int) -> None:
    parser.add_argument("--steps", type=positive_int, default=default_steps, help=f"(default {default_steps})")
    parser.add_argument("--out", type=Path, required=True, help="run folder")
    parser.add_argument("--data", default="procedural",
                        help="'procedural' (seeded night scenes) or a folder of .exr/.hdr files")
    parser.add_argument("--batch", type=positive_int, default=4)
    parser.add_argument("--crop", type=positive_int, default=128, metavar="PX", help="crop size (multiple of 16)")
    parser.add_argument("--lr", type=positive_float, default=None, help="network learning rate")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--checkpoint-every", type=positive_int, default=100, metavar="K")
    parser.add_argument("--resume", action="store_true", help="continue the run in --out from its checkpoint")
    parser.add_argument("--vgg-weights", type=Path, default=None,
                        help="torchvision VGG-19 state dict (preset paper; or set HDRCAM_VGG19_WEIGHTS)")
    parser.add_argument("--random-vgg", action="store_true",
                        help="use random VGG-19 features when no weights exist (tests only: no perceptual meaning)")
    parser.add_argument("--device", default="auto", choices=("auto", "cpu", "cuda"))


def register(commands) -> None:
    design = commands.add_parser("design", help="end-to-end design of the DOE and the network",
                                 description="Jointly optimise a DOE height map and the reconstruction network "
                                             "through the simulated optics and sensor (paper Sec. 3-4), or train "
                                             "the network alone behind a fixed PSF (--psf).")
    design.add_argument("--preset", choices=tuple(PRESETS), default="fast")
    design.add_argument("--profile", default="simulated", help="capture profile (default simulated)")
    choice = design.add_mutually_exclusive_group()
    choice.add_argument("--doe", choices=TRAINABLE_DOES, default=None, help="trained height map (default rank1)")
    choice.add_argument("--psf", default=None, metavar="|".join(FIXED_PSFS) + "|FILE",
                        help="a fixed PSF: train the network only (dirac, star8 and dual-peak are imaged "
                             "through the profile's bare lens)")
    _training_options(design, 1000)
    design.set_defaults(run=run_design)

    finetune = commands.add_parser("finetune", help="fine-tune a network on a measured PSF",
                                   description="Train a checkpoint's network (not its DOE) behind a measured PSF, "
                                               "e.g. calibration/NAME/psf.exr.")
    finetune.add_argument("--checkpoint", type=Path, default=None, help="start from this (default: the shipped one)")
    finetune.add_argument("--psf", type=Path, required=True, help="PSF EXR, e.g. calibration/NAME/psf.exr")
    _training_options(finetune, 200)
    finetune.set_defaults(run=run_finetune)


def _config(arguments: argparse.Namespace, **fields) -> TrainConfig:
    from hdrcam.train.config import TrainConfig

    config = TrainConfig(data=arguments.data, steps=arguments.steps, batch=arguments.batch, crop_px=arguments.crop,
                         seed=arguments.seed, checkpoint_every=arguments.checkpoint_every, **fields)
    if arguments.lr:
        config.learning_rate = arguments.lr
    return config


def _train(config: TrainConfig, arguments: argparse.Namespace) -> int:
    from hdrcam.train.design import train

    started = time.perf_counter()
    last = train(config, arguments.out, resume=arguments.resume, vgg_weights=arguments.vgg_weights,
                 random_vgg=arguments.random_vgg, device=compute_device(arguments.device))
    if os.environ.get("RANK", "0") != "0":  # under torchrun only the first process reports
        return 0
    print(json.dumps({"run": str(arguments.out), "model": str(arguments.out / "model.pt"),
                      "seconds": round(time.perf_counter() - started, 1), "last_step": last}))
    return 0


def run_design(arguments: argparse.Namespace) -> int:
    if arguments.psf and arguments.psf not in FIXED_PSFS and not Path(arguments.psf).is_file():
        raise InputError(f"--psf {arguments.psf}: not one of {', '.join(FIXED_PSFS)} and no such file")
    doe = None if arguments.psf else (arguments.doe or "rank1")
    config = _config(arguments, preset=arguments.preset, profile=arguments.profile, doe=doe, psf=arguments.psf)
    return _train(config, arguments)


def run_finetune(arguments: argparse.Namespace) -> int:
    from hdrcam.train.checkpoint import SHIPPED_CHECKPOINT, read_checkpoint

    checkpoint = arguments.checkpoint or SHIPPED_CHECKPOINT
    state = read_checkpoint(checkpoint)
    if not arguments.psf.is_file():
        raise InputError(f"--psf {arguments.psf} does not exist")
    config = _config(arguments, preset=state["preset"], profile=state["profile"], doe=None, psf=str(arguments.psf),
                     init_checkpoint=str(checkpoint))
    if not arguments.lr:
        config.learning_rate = 2e-4  # a gentler start than from scratch: the network already works
    return _train(config, arguments)
