"""Training and validation curves of a run: training loss per step, and each snapshot scored on held-out scenes.

    .venv/bin/python tools/validation_curve.py RUN --snapshots RUN/snapshots --data runs/data/val \
        [--data procedural] --out tools/results/real-data/curves

RUN holds log.jsonl (hdrcam design/finetune); --snapshots holds checkpoints named step-N.pt (copies of
RUN/checkpoint.pt taken as training went). Every snapshot is scored with ``hdrcam evaluate``'s own function
(the full pipeline, :func:`hdrcam.api.reconstruct`, and the network alone) on each --data set: mean linear
PSNR gain over the LDR capture (dB, peak 2^8) and the worst photograph's gain. Writes curves.csv (after each
snapshot; steps already in it are not scored again) and curves.png (training loss smoothed over 100 steps; validation gains per snapshot).
"""

from __future__ import annotations

import argparse
import csv
import json
import re
import sys
from pathlib import Path

import numpy as np

from hdrcam.data.scenes import SceneSource
from hdrcam.evaluate.report import gains_over
from hdrcam.evaluate.scoring import evaluate_models
from hdrcam.io.png import write_png
from hdrcam.preview import line_plot, side_by_side
from hdrcam.train.checkpoint import load_model
from one_line_errors import run  # tools/ is on sys.path when a tool runs

SIZE_PX = 512  # the paper's test crop
PROCEDURAL_COUNT = 16


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", type=Path)
    parser.add_argument("--snapshots", type=Path, required=True)
    parser.add_argument("--data", action="append", required=True, help="held-out set (repeatable)")
    parser.add_argument("--every", type=int, default=1, help="score every K-th snapshot (and the last)")
    parser.add_argument("--out", type=Path, required=True)
    arguments = parser.parse_args(argv)
    snapshots = sorted(arguments.snapshots.glob("step-*.pt"), key=lambda p: int(re.findall(r"\d+", p.stem)[0]))
    if not snapshots:
        print(f"error: no step-N.pt snapshots in {arguments.snapshots}", file=sys.stderr)
        return 1
    snapshots = [p for i, p in enumerate(snapshots) if i % arguments.every == 0 or p == snapshots[-1]]
    arguments.out.mkdir(parents=True, exist_ok=True)
    sources = {data: SceneSource(data) for data in arguments.data}
    scored = {}
    if (arguments.out / "curves.csv").exists():  # steps scored by an earlier call are kept, not re-run
        with (arguments.out / "curves.csv").open(newline="") as handle:
            scored = {int(row["step"]): {k: (int(v) if k == "step" else float(v)) for k, v in row.items()}
                      for row in csv.DictReader(handle)}
    records = []
    for snapshot in snapshots:
        step = int(re.findall(r"\d+", snapshot.stem)[0])
        if step in scored:
            records.append(scored[step])
            continue
        model = load_model(snapshot)
        record = {"step": model.step}
        for data, source in sources.items():
            count = PROCEDURAL_COUNT if source.folder is None else len(source.folder)
            rows, _ = evaluate_models({"hdrcam": model}, source, size_px=SIZE_PX, count=count, examples=0)
            name = Path(data).name
            for method in ("hdrcam", "hdrcam-network"):
                values = gains_over(rows, method)
                record[f"{name}:{method}:mean"] = round(float(np.mean(values)), 3)
                record[f"{name}:{method}:worst"] = round(float(np.min(values)), 3)
        records.append(record)
        print(json.dumps(record), flush=True)
        with (arguments.out / "curves.csv").open("w", newline="") as handle:
            writer = csv.DictWriter(handle, fieldnames=list(records[0]))
            writer.writeheader()
            writer.writerows(sorted(records, key=lambda r: r["step"]))
    log = [json.loads(line) for line in (arguments.run / "log.jsonl").read_text().splitlines() if line]
    steps = np.array([entry["step"] for entry in log])
    totals = np.cumsum(np.concatenate([[0.0], [entry["total"] for entry in log]]))
    window = np.minimum(np.arange(1, len(log) + 1), 100)
    smoothed = (totals[1:] - totals[np.arange(1, len(log) + 1) - window]) / window
    steps_scored = np.array([record["step"] for record in records])
    validation = {key.replace(":mean", " mean gain"): (steps_scored, np.array([r[key] for r in records]))
                  for key in records[0] if key.endswith(":mean")}
    figure = side_by_side([line_plot({"training loss (100-step mean)": (steps, smoothed)}, "training loss"),
                           line_plot(validation, "validation: linear PSNR over LDR (dB)", log_y=False)],
                          height_px=400)
    write_png(arguments.out / "curves.png", figure, overwrite=True)
    print(f"wrote {arguments.out}/curves.csv and curves.png")
    return 0


if __name__ == "__main__":
    sys.exit(run(main))
