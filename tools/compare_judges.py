"""How each way of judging the network's estimate by its frame scores, on held-out scenes.

    .venv/bin/python tools/compare_judges.py --checkpoint C --data runs/data/val --data procedural \
        [--judge NAME=MODULE.py ...] --out tools/results/real-data/judges.md

Rows (the checkpoint's network alone, without its partner: the judges are what is compared): the network
alone; the shipped judge (hdrcam.recon.consistency, what ``reconstruct`` does); the same
without its evidence step (upper bound only); the shipped judge after the optional streak fit; and any
alternative judge given as a module file defining ``make_consistent`` with the shipped signature (e.g. an
earlier version from git: ``git show COMMIT:hdrcam/recon/consistency.py > old.py``). Every row goes through
``hdrcam.evaluate.scoring.evaluate_models`` (the paper's protocol: 512^2 crops, 1.5 % clipped, linear PSNR,
peak 2^8) with the judge swapped in; columns: mean gain over the LDR capture, the worst scene's gain and how
many scenes lose more than 0.3 dB, per data set.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import importlib.util
import sys
from pathlib import Path

import numpy as np

import hdrcam.api as api
import hdrcam.evaluate.scoring as scoring
import hdrcam.recon.consistency as consistency
from hdrcam.data.scenes import SceneSource
from hdrcam.io.atomic import write_text_atomic
from hdrcam.evaluate.metrics import HARM_DB
from hdrcam.evaluate.report import gains_over
from hdrcam.train.checkpoint import load_model
from one_line_errors import refuse_existing, run  # tools/ is on sys.path when a tool runs

SIZE_PX = 512
PROCEDURAL_COUNT = 16


def _module(path: Path):
    spec = importlib.util.spec_from_file_location(f"judge_{path.stem}", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up while the file runs
    spec.loader.exec_module(module)
    return module


@contextlib.contextmanager
def judged_by(make_consistent=None, streak_fit=False, evidence=True):
    """Swap the judge, the streak fit and the evidence step of hdrcam.api.reconstruct for one block."""
    saved = api.make_consistent, scoring.reconstruct, consistency._evidence_shares
    try:
        if make_consistent is not None:
            api.make_consistent = make_consistent
        if streak_fit:
            scoring.reconstruct = functools.partial(api.reconstruct, streak_fit=True)
        if not evidence:
            consistency._evidence_shares = lambda *arguments: (np.ones(3, np.float32), -np.inf)
        yield
    finally:
        api.make_consistent, scoring.reconstruct, consistency._evidence_shares = saved


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--checkpoint", type=Path, default=None)
    parser.add_argument("--data", action="append", required=True)
    parser.add_argument("--judge", action="append", default=[], metavar="NAME=MODULE.py")
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--overwrite", action="store_true", help="replace an existing --out report")
    arguments = parser.parse_args(argv)
    refuse_existing(arguments.out, arguments.overwrite)
    model = load_model(arguments.checkpoint)
    sources = {data: SceneSource(data) for data in arguments.data}
    judges = {"shipped judge (reconstruct)": {}, "upper bound only (no evidence step)": {"evidence": False},
              "streak fit, then the shipped judge": {"streak_fit": True}}
    for entry in arguments.judge:
        name, _, path = entry.partition("=")
        judges[name] = {"make_consistent": _module(Path(path)).make_consistent}
    results: dict[str, dict[str, np.ndarray]] = {"network alone": {}}
    for name, options in judges.items():
        results[name] = {}
        with judged_by(**options):
            for data, source in sources.items():
                count = PROCEDURAL_COUNT if source.folder is None else len(source.folder)
                rows, _ = scoring.evaluate_models({"hdrcam": model}, source, size_px=SIZE_PX, count=count,
                                                   examples=0, partner=None)  # one network: the judges compared
                results[name][data] = gains_over(rows, "hdrcam")
                results["network alone"].setdefault(data, gains_over(rows, "hdrcam-network"))
        print(name, {data: round(float(values.mean()), 2) for data, values in results[name].items()}, flush=True)
    header = "| judge | " + " | ".join(f"{data}: mean gain (worst), scenes < -{HARM_DB} dB" for data in sources) + " |"
    lines = [f"Checkpoint {model.source} (step {model.step}); linear PSNR gain over the LDR capture, dB.", "",
             header, "|---|" + "---|" * len(sources)]
    for name, per_data in results.items():
        cells = [f"{v.mean():+.2f} ({v.min():+.2f}), {int((v < -HARM_DB).sum())}" for v in per_data.values()]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    text = "\n".join(lines) + "\n"
    arguments.out.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(arguments.out, text, overwrite=arguments.overwrite)
    print(text, end="")
    return 0


if __name__ == "__main__":
    sys.exit(run(main))
