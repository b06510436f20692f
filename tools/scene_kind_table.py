"""Per-scene-kind table of ``hdrcam evaluate`` results on catalogued photographs.

    .venv/bin/python tools/scene_kind_table.py --split runs/data/split.csv \
        --metrics EVAL/metrics.csv [--metrics no-doe=EVAL_DIRAC/metrics.csv] --out TABLE.md

Each --metrics is an evaluate run's metrics.csv; a LABEL= prefix renames that run's checkpoint rows (e.g. the
same network scored on frames captured through the bare lens, ``evaluate --psf``) and drops its ldr and
hdrcnn-blend rows, which belong to the first run. Rows: scene kinds (from split.csv, by image stem) and
'all'; columns: linear PSNR (dB, peak 2^8) of each method as its mean gain over the FIRST run's LDR capture
(one reference for every column, so columns compare directly), that LDR mean itself, the worst photograph's
gain, and how many photographs the first run's pipeline (``hdrcam``, or the name evaluate gave its
--checkpoint) leaves more than 0.3 dB below its LDR.
"""

from __future__ import annotations

import argparse
import csv
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

from hdrcam.evaluate.metrics import HARM_DB  # the generalisation issue's bar
from hdrcam.io.atomic import write_text_atomic
from one_line_errors import refuse_existing, run  # tools/ is on sys.path when a tool runs


def read_runs(entries: list[str]) -> dict[str, dict[str, float]]:
    """--metrics entries -> {image: {method: psnr_linear}}."""
    scores: dict[str, dict[str, float]] = defaultdict(dict)
    for index, entry in enumerate(entries):
        label, _, path = entry.rpartition("=")
        with open(path, newline="") as handle:
            for row in csv.DictReader(handle):
                method = row["method"]
                if index and method == "hdrcnn-blend":
                    continue
                if index and method == "ldr":
                    method = f"{label or index}:ldr"  # that camera's own capture, e.g. without the DOE
                elif label:
                    method = method.replace("hdrcam", label, 1) if method.startswith("hdrcam") else f"{label}:{method}"
                scores[row["image"]][method] = float(row["psnr_linear"])
    return scores


def table(scores: dict[str, dict[str, float]], kinds: dict[str, str]) -> str:
    methods = [m for m in next(iter(scores.values())) if m != "ldr"]
    # the first run's full pipeline: `hdrcam` for the default checkpoint, else the name evaluate gave --checkpoint
    pipeline = next(m for m in methods if m != "hdrcnn-blend" and not m.endswith("-network") and ":" not in m)
    groups = defaultdict(list)
    for image in scores:
        groups[kinds.get(image, "unknown")].append(image)
    lines = ["| scene kind | photos | LDR (dB) | " + " | ".join(f"{m}: gain (worst)" for m in methods)
             + f" | photos > 0.3 dB below LDR ({pipeline}) |",
             "|---|---|---|" + "---|" * len(methods) + "---|"]
    for kind in sorted(groups) + ["all"]:
        images = list(scores) if kind == "all" else groups[kind]
        ldr = np.array([scores[i]["ldr"] for i in images])
        cells = []
        for method in methods:
            gain = np.array([scores[i][method] for i in images]) - ldr
            cells.append(f"{gain.mean():+.2f} ({gain.min():+.2f})")
        harmed = sum(scores[i][pipeline] - scores[i]["ldr"] < -HARM_DB for i in images)
        lines.append(f"| {kind} | {len(images)} | {ldr.mean():.2f} | " + " | ".join(cells) + f" | {harmed} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--split", type=Path, required=True, help="split.csv of tools/split_hdr_train.py")
    parser.add_argument("--metrics", action="append", required=True, help="[LABEL=]metrics.csv (repeatable)")
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--overwrite", action="store_true", help="replace an existing --out table")
    arguments = parser.parse_args(argv)
    refuse_existing(arguments.out, arguments.overwrite)
    with arguments.split.open(newline="") as handle:
        kinds = {row["file"].rsplit(".", 1)[0]: row["scene_kind"] for row in csv.DictReader(handle)}
    text = table(read_runs(arguments.metrics), kinds)
    write_text_atomic(arguments.out, text, overwrite=arguments.overwrite)
    print(text, end="")
    return 0


if __name__ == "__main__":
    sys.exit(run(main))
