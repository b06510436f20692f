"""``hdrcam evaluate``: score checkpoints on a test set against the LDR capture and HDR-CNN-style blending."""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import time
import warnings
from pathlib import Path

from hdrcam.cli.arguments import positive_int, random_seed
from hdrcam.errors import InputError, escaped_name
from hdrcam.io.atomic import check_outputs


def register(commands) -> None:
    parser = commands.add_parser("evaluate", help="metrics and ablation tables on a test set",
                                 description=__doc__)
    parser.add_argument("--checkpoint", action="append", default=None, metavar="[LABEL=]FILE",
                        help="a checkpoint to score; repeat for a comparison table (default: the shipped one)")
    parser.add_argument("--psf", type=Path, default=None,
                        help="capture through this PSF EXR instead of each checkpoint's own")
    parser.add_argument("--data", default="procedural", help="'procedural' or a folder of .exr/.hdr files")
    parser.add_argument("--size", type=positive_int, default=512, metavar="PX", help="test crop (multiple of 16)")
    parser.add_argument("--count", type=positive_int, default=16, help="procedural test scenes (default 16)")
    parser.add_argument("--seed", type=random_seed, default=0, help="noise seed of the captures")
    parser.add_argument("--no-mirror-check", dest="mirror_check", action="store_false",
                        help="score reconstruct's one-pass option (no mirror-image second opinion)")
    parser.add_argument("--place-highlights", action="store_true",
                        help="score reconstruct --place-highlights (light placed where long streaks point)")
    partners = parser.add_mutually_exclusive_group()
    partners.add_argument("--partner", type=Path, default=None, metavar="CHECKPOINT",
                          help="score reconstruct --partner: every checkpoint with this second network (default: "
                               "each checkpoint's own NAME-partner.pt beside it, where there is one)")
    partners.add_argument("--no-partner", action="store_true",
                          help="score reconstruct --no-partner: each checkpoint's network alone")
    parser.add_argument("--out", type=Path, default=None,
                        help="output folder (default: a new evaluate-YYYYMMDD-HHMMSS in the working directory)")
    parser.add_argument("--vgg-weights", type=Path, default=None)
    parser.add_argument("--overwrite", action="store_true")
    parser.set_defaults(run=run)


def _labelled(entries: list[str] | None) -> dict[str, Path | None]:
    from hdrcam.evaluate.scoring import NETWORK_SUFFIX

    if not entries:
        return {"hdrcam": None}
    labelled = {}
    for entry in entries:
        label, _, path = entry.rpartition("=")
        path = Path(path)
        label = label or (path.parent.name if path.name in ("model.pt", "checkpoint.pt") else path.stem)
        if label in labelled or label in ("ldr", "hdrcnn-blend"):
            raise InputError(f"checkpoint label {label!r} is used twice or reserved; write LABEL=FILE")
        labelled[label] = path
    for label in labelled:  # each label's network alone is scored as LABEL-network
        if label.endswith(NETWORK_SUFFIX) and label[:-len(NETWORK_SUFFIX)] in labelled:
            raise InputError(f"checkpoint label {label!r} is the name of {label[:-len(NETWORK_SUFFIX)]!r}'s network "
                             "alone; write another LABEL=FILE")
    return labelled


def fresh_output_folder() -> Path:
    """A folder name in the working directory that nothing holds yet: evaluate-YYYYMMDD-HHMMSS (local time), with
    -2, -3, ... after it where that is taken, so a run without --out never overwrites an earlier one."""
    stem = time.strftime("evaluate-%Y%m%d-%H%M%S")
    folder, number = Path(stem), 1
    while os.path.lexists(folder):  # a link by that name, even a broken one, is taken too
        number += 1
        folder = Path(f"{stem}-{number}")
    return folder


@contextlib.contextmanager
def _warnings_on_lines_of_their_own():
    """Warnings shown while a progress bar is on stderr's line go on lines of their own, the bar cleared and
    redrawn below them (tqdm.external_write_mode, as reconstruct's), not run on from the bar."""
    from tqdm import tqdm

    shown = warnings.showwarning

    def show(*arguments, **keywords):
        with tqdm.external_write_mode(file=sys.stderr):
            shown(*arguments, **keywords)

    warnings.showwarning = show
    try:
        yield
    finally:
        warnings.showwarning = shown


def run(arguments: argparse.Namespace) -> int:
    with _warnings_on_lines_of_their_own():
        return _run(arguments)


def _run(arguments: argparse.Namespace) -> int:
    from tqdm import tqdm

    from hdrcam.data.scenes import PROCEDURAL, SceneSource
    from hdrcam.evaluate.report import OUTPUT_NAMES, summary_markdown, write_report
    from hdrcam.evaluate.scoring import check_test_crop, evaluate_models
    from hdrcam.optics.psf_file import load_psf
    from hdrcam.limits import check_image_size
    from hdrcam.recon.tiling import FRAME_BYTES_PER_PIXEL, WINDOW_BYTES_PER_PIXEL
    from hdrcam.api import resolve_partner
    from hdrcam.train.checkpoint import load_model

    started = time.perf_counter()  # the time printed at the end: reading, cropping and scoring
    check_test_crop(arguments.size)
    if arguments.out is None:
        arguments.out = fresh_output_folder()
    check_image_size("--size", arguments.size, arguments.size, WINDOW_BYTES_PER_PIXEL + FRAME_BYTES_PER_PIXEL,
                     "use a smaller --size")
    inputs = [path for path in (*_labelled(arguments.checkpoint).values(), arguments.psf) if path is not None]
    check_outputs([arguments.out / name for name in OUTPUT_NAMES], overwrite=arguments.overwrite, inputs=inputs)
    models = {label: load_model(path, vgg_weights=arguments.vgg_weights)
              for label, path in _labelled(arguments.checkpoint).items()}
    psf = load_psf(arguments.psf) if arguments.psf else None
    wanted = None if arguments.no_partner else (
        load_model(arguments.partner, vgg_weights=arguments.vgg_weights) if arguments.partner else "auto")
    partners = {label: resolve_partner(model, wanted, vgg_weights=arguments.vgg_weights)
                for label, model in models.items()}  # before any scoring
    with tqdm(desc="read", unit="file", disable=arguments.data == PROCEDURAL) as reading:
        source = SceneSource(arguments.data, lenient=True, progress=reading)
    count = arguments.count if source.folder is None else len(source.folder)
    noun = "test scenes" if source.folder is None else "photographs"
    unscored = [] if source.folder is None else [(escaped_name(path.name), reason)
                                                 for path, reason in source.folder.skipped]
    with tqdm(total=count, desc="evaluate", unit="image") as progress:
        rows, examples = evaluate_models(models, source, size_px=arguments.size, count=count, psf=psf,
                                         seed=arguments.seed, mirror_check=arguments.mirror_check,
                                         place_highlights=arguments.place_highlights,
                                         partner=partners, progress=progress, unscored=unscored)
    if not rows:
        shown = 3  # of the reasons: one line, however many photographs
        reasons = "; ".join(f"{name}: {reason}" for name, reason in unscored[:shown])
        more = f"; and {len(unscored) - shown} more, named in the warnings above" if len(unscored) > shown else ""
        raise InputError(f"{arguments.data}: none of its {len(unscored)} {noun} could be scored ({reasons}{more}); "
                         "nothing scored")
    description = (f"Test set: {source.description} ({arguments.size}x{arguments.size} crops, exactly 1.5 % of "
                   f"pixels above 1, clipped at 2^8), captured with noise seed {arguments.seed} through "
                   f"{'the PSF ' + str(arguments.psf) if psf is not None else 'each checkpoint’s own PSF'}. "
                   f"Checkpoints: " + ", ".join(f"{label} = {model.source} (preset {model.preset}, step {model.step})"
                                                for label, model in models.items()) + ".")
    paired = [f"{label} with {partner.source}" for label, partner in partners.items() if partner is not None]
    if paired:
        description += (" Partner networks (reconstruct keeps what both paint unless the streaks confirm one): "
                        + ", ".join(paired) + ".")
    write_report(arguments.out, rows, examples, description, overwrite=arguments.overwrite, unscored=unscored,
                 noun=noun)
    print(summary_markdown(rows, description, unscored=unscored, noun=noun), end="")
    written = "metrics.csv, summary.md" + (", examples.jpg" if examples else "")
    print(f"evaluated in {time.perf_counter() - started:.1f} s; wrote {arguments.out}/{written}")
    return 0
