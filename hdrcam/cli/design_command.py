"""``hdrcam design`` and ``hdrcam finetune``: train a DOE and network end to end, or a network on a fixed PSF."""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from hdrcam.cli.arguments import (non_negative_finite_float, non_negative_int, positive_finite_float, positive_int,
                                  random_seed)
from hdrcam.recon.presets import PRESETS
from hdrcam.train.choices import FIXED_PSFS, TRAINABLE_DOES


def _training_options(parser: argparse.ArgumentParser, default_steps: int) -> None:
    """Options left out take the run's own values with --resume, and these defaults for a new run."""
    parser.add_argument("--steps", type=positive_int, default=None, help=f"(default {default_steps})")
    parser.add_argument("--out", type=Path, required=True, help="run folder")
    parser.add_argument("--data", default=None,
                        help="'procedural' (seeded night scenes, the default), a folder of .exr/.hdr files, or a "
                             "mixture SOURCE:WEIGHT,... (e.g. runs/data/train:0.6,procedural:0.3,photos:0.1)")
    parser.add_argument("--batch", type=positive_int, default=None, help="(default 4)")
    parser.add_argument("--crop", type=positive_int, default=None, metavar="PX",
                        help="crop size (multiple of 16, default 128)")
    parser.add_argument("--lr", type=positive_finite_float, default=None, help="network learning rate")
    parser.add_argument("--seed", type=random_seed, default=None, help="(default 0)")
    parser.add_argument("--checkpoint-every", type=positive_int, default=None, metavar="K", help="(default 100)")
    parser.add_argument("--resume", action="store_true",
                        help="continue the run in --out from its checkpoint; options given must match the run's")
    parser.add_argument("--vgg-weights", type=Path, default=None,
                        help="torchvision VGG-19 state dict (preset paper; or set HDRCAM_VGG19_WEIGHTS)")
    parser.add_argument("--random-vgg", action="store_true",
                        help="use random VGG-19 features when no weights exist (tests only: no perceptual meaning)")
    parser.add_argument("--device", default="auto", choices=("auto", "cpu", "cuda"))
    parser.add_argument("--precision", choices=("float32", "bfloat16", "float16"), default=None,
                        help="the network's forward in training (default float32; bfloat16/float16 autocast on a "
                             "GPU, float16 CUDA only; optics and losses stay float32)")
    parser.add_argument("--channels-last", action="store_true", default=None,
                        help="NHWC network weights and input (faster on CUDA tensor cores)")
    parser.add_argument("--data-workers", type=non_negative_int, default=None, metavar="N",
                        help="CPU threads drawing scenes ahead of each step (default: 0 on a CPU, drawing each "
                             "batch when the step asks, else one per scene of a batch, leaving a core free); "
                             "results do not depend on it")
    parser.add_argument("--linear-gain-weight", type=non_negative_finite_float, default=None, metavar="W",
                        help="weight, per dB, of a loss term that is minus each scene's linear-PSNR gain over its "
                             "captured frame - the evaluation's measure, which a few pixels of a sun dominate "
                             "(default 0: the paper's losses alone)")


def register(commands) -> None:
    design = commands.add_parser("design", help="end-to-end design of the DOE and the network",
                                 description="Jointly optimise a DOE height map and the reconstruction network "
                                             "through the simulated optics and sensor (paper Sec. 3-4), or train "
                                             "the network alone behind a fixed PSF (--psf).")
    design.add_argument("--preset", choices=tuple(PRESETS), default=None, help="(default fast)")
    design.add_argument("--profile", default=None, help="capture profile (default simulated)")
    choice = design.add_mutually_exclusive_group()
    choice.add_argument("--doe", choices=TRAINABLE_DOES, default=None, help="trained height map (default rank1)")
    choice.add_argument("--psf", default=None, metavar="|".join(FIXED_PSFS) + "|FILE",
                        help="a fixed PSF: train the network only (dirac, star8 and dual-peak are imaged "
                             "through the profile's bare lens)")
    design.add_argument("--init", type=Path, default=None, metavar="CHECKPOINT",
                        help="start the network from this checkpoint's weights (same preset), e.g. to give every "
                             "row of Table 2 the same starting network")
    design.add_argument("--init-doe", type=Path, default=None, metavar="CHECKPOINT",
                        help="start the trained DOE from this checkpoint's DOE (same --doe kind and profile), e.g. "
                             "a PSF-first design such as hdrcam/checkpoints/table2/rank1.pt")
    _training_options(design, 1000)
    design.set_defaults(run=run_design)

    finetune = commands.add_parser("finetune", help="fine-tune a network on a measured PSF",
                                   description="Train a checkpoint's network (not its DOE) behind a measured PSF, "
                                               "e.g. calibration/NAME/psf.exr, and then its partner network "
                                               "(see --no-partner).")
    finetune.add_argument("--checkpoint", type=Path, default=None, help="start from this (default: the shipped one)")
    finetune.add_argument("--psf", type=Path, default=None,
                          help="PSF EXR, e.g. calibration/NAME/psf.exr (with --resume: the run's own by default)")
    finetune.add_argument("--no-partner", dest="partner", action="store_false", default=None,
                          help="fine-tune the checkpoint alone. By default, when it has a partner (NAME-partner.pt "
                               "beside NAME.pt: a second network trained behind the same PSF, which reconstruct "
                               "runs with it and keeps what both paint; the shipped checkpoint has one), the "
                               "partner is fine-tuned next with the same options in OUT/partner and written to "
                               "OUT/model-partner.pt (twice the training time). --resume follows the choice the "
                               "run was started with")
    checked = finetune.add_mutually_exclusive_group()
    checked.add_argument("--check-data", default="procedural", metavar="DATA",
                         help="held-out scenes the fine-tuned networks are scored on against the start ones, "
                              "behind the PSF: 'procedural' (default) or a folder of photographs kept out of "
                              "--data; where the fine-tuned ones score lower, OUT/model.pt holds the start networks "
                              "and the fine-tuned ones are kept as OUT/model-finetuned.pt (OUT/check.json)")
    checked.add_argument("--no-check", dest="check_data", action="store_const", const=None,
                         help="keep the fine-tuned networks unchecked (saves ~15 s on a 2-core CPU)")
    _training_options(finetune, 200)
    finetune.set_defaults(run=run_finetune)


def _train(stage, arguments: argparse.Namespace, summary=None, **fields) -> int:
    """Run ``stage`` (hdrcam.stages.design or finetune) with the options given; print the run's summary (plus
    what ``summary`` returns after the run)."""
    started = time.perf_counter()
    last = stage(out=arguments.out, data=arguments.data, steps=arguments.steps, batch=arguments.batch,
                 crop_px=arguments.crop, learning_rate=arguments.lr, seed=arguments.seed,
                 checkpoint_every=arguments.checkpoint_every, precision=arguments.precision,
                 channels_last=arguments.channels_last, resume=arguments.resume, vgg_weights=arguments.vgg_weights,
                 random_vgg=arguments.random_vgg, device=arguments.device, data_workers=arguments.data_workers,
                 linear_gain_weight=arguments.linear_gain_weight, **fields)
    from hdrcam.stages import first_process

    if not first_process():  # under torchrun only the first process reports
        return 0
    print(json.dumps({"run": str(arguments.out), "model": str(arguments.out / "model.pt"),
                      **(summary() if summary else {}), "seconds": round(time.perf_counter() - started, 1),
                      "last_step": last}))
    return 0


def run_design(arguments: argparse.Namespace) -> int:
    from hdrcam.stages import design

    return _train(design, arguments, preset=arguments.preset, profile=arguments.profile, doe=arguments.doe,
                  psf=arguments.psf, init=arguments.init, init_doe=arguments.init_doe)


def run_finetune(arguments: argparse.Namespace) -> int:
    from hdrcam.stages import PARTNER_RUN, finetune, finetune_check_record, finetuned_partner

    def partner_summary() -> dict:
        """The partner fine-tuned in OUT/partner and where its network was written (null without one), and the
        check's record (null where none ran)."""
        written = finetuned_partner(arguments.out)
        return {"partner": {"run": str(arguments.out / PARTNER_RUN), "model": str(written)} if written else None,
                "check": finetune_check_record(arguments.out) if arguments.check_data is not None else None}

    return _train(finetune, arguments, partner_summary, psf=arguments.psf, checkpoint=arguments.checkpoint,
                  partner=arguments.partner, check=arguments.check_data)
