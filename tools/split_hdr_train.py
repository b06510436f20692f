"""Split a catalogued folder of real HDR photographs into training and validation folders, by scene kind.

    .venv/bin/python tools/split_hdr_train.py ../shared/data/hdr-train --out runs/data

Reads CATALOG (catalog.csv: file, scene_kind, sha256, ...) and, within each scene kind, sends every
VALIDATION_EVERY-th photograph (ordered by sha256, so the split does not depend on file names or on the
order files were added) to validation; a kind with a single photograph stays in training. Writes
OUT/train/ and OUT/val/ as symbolic links to the photographs (no copies) and OUT/split.csv (file,
scene_kind, split). The validation folder is never trained on: pass OUT/train to ``hdrcam design
--data`` and OUT/val to ``hdrcam evaluate --data``.
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
from collections import defaultdict
from pathlib import Path
from one_line_errors import run  # tools/ is on sys.path when a tool runs

VALIDATION_EVERY = 4  # a quarter of each scene kind, rounded up


def split(rows: list[dict]) -> dict[str, str]:
    """catalog rows -> {file: 'train' | 'val'} (module docstring)."""
    by_kind = defaultdict(list)
    for row in rows:
        by_kind[row["scene_kind"]].append(row)
    assignment = {}
    for kind, members in by_kind.items():
        members.sort(key=lambda row: row["sha256"])
        held_out = 0 if len(members) < 2 else math.ceil(len(members) / VALIDATION_EVERY)
        for index, row in enumerate(members):
            assignment[row["file"]] = "val" if index < held_out else "train"
    return assignment


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", type=Path, help="folder with the photographs and catalog.csv")
    parser.add_argument("--out", type=Path, required=True, help="where train/, val/ and split.csv go")
    arguments = parser.parse_args(argv)
    catalog = arguments.folder / "catalog.csv"
    if not catalog.is_file():
        print(f"error: {catalog} does not exist", file=sys.stderr)
        return 1
    with catalog.open(newline="") as handle:
        rows = list(csv.DictReader(handle))
    missing = [row["file"] for row in rows if not (arguments.folder / row["file"]).is_file()]
    if missing:
        print(f"error: {len(missing)} catalogued files are missing, e.g. {missing[0]}", file=sys.stderr)
        return 1
    assignment = split(rows)
    for part in ("train", "val"):
        (arguments.out / part).mkdir(parents=True, exist_ok=True)
    for row in rows:
        link = arguments.out / assignment[row["file"]] / row["file"]
        if not link.exists():
            link.symlink_to((arguments.folder / row["file"]).resolve())
    with (arguments.out / "split.csv").open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["file", "scene_kind", "split"])
        for row in sorted(rows, key=lambda row: (assignment[row["file"]], row["scene_kind"], row["file"])):
            writer.writerow([row["file"], row["scene_kind"], assignment[row["file"]]])
    counts = {part: sum(1 for value in assignment.values() if value == part) for part in ("train", "val")}
    print(f"{counts['train']} training and {counts['val']} validation photographs in {arguments.out}")
    return 0


if __name__ == "__main__":
    sys.exit(run(main))
