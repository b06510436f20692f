"""Evaluation outputs: metrics.csv (one row per image and method), summary.md (means) and
examples.jpg (tone-mapped truth and methods side by side)."""

from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np

from hdrcam.errors import escaped_name
from hdrcam.evaluate.metrics import HARM_DB
from hdrcam.evaluate.scoring import Example, ScoredImage
from hdrcam.io.atomic import atomic_paths, write_text_atomic
from hdrcam.io.jpeg import write_jpeg
from hdrcam.preview import log_average_luminance, tonemap_rgb

METRICS = ("psnr_linear", "pu21_psnr", "psnr_mu")
OUTPUT_NAMES = ("metrics.csv", "summary.md", "examples.jpg")


def method_means(rows: list[ScoredImage]) -> dict[str, dict[str, float]]:
    """Mean of each metric per method, in the order methods first appear."""
    means: dict[str, dict[str, float]] = {}
    for method in dict.fromkeys(row.method for row in rows):
        chosen = [row for row in rows if row.method == method]
        means[method] = {metric: float(np.mean([row.metrics[metric] for row in chosen])) for metric in METRICS}
    return means


def metrics_csv(rows: list[ScoredImage]) -> str:
    """metrics.csv's text: one row per image and method."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(["image", "method", *METRICS, "clipped_fraction"])
    for row in rows:
        writer.writerow([row.image, row.method, *(f"{row.metrics[m]:.4f}" for m in METRICS),
                         f"{row.clipped_fraction:.5f}"])
    return buffer.getvalue()


def paired_gains(rows: list[ScoredImage], method: str, reference: str = "ldr") -> list[tuple[str, float]]:
    """(image, linear-PSNR gain in dB of ``method`` over ``reference``) for each image both were scored on, in
    the order the images were scored."""
    base = {row.image: row.metrics["psnr_linear"] for row in rows if row.method == reference}
    return [(row.image, row.metrics["psnr_linear"] - base[row.image]) for row in rows
            if row.method == method and row.image in base]


def gains_over(rows: list[ScoredImage], method: str, reference: str = "ldr") -> np.ndarray:
    """The gains of :func:`paired_gains` alone (dB)."""
    return np.array([gain for _, gain in paired_gains(rows, method, reference)])


def summary_markdown(rows: list[ScoredImage], description: str, reference: str = "ldr",
                     unscored: list[tuple[str, str]] = (), noun: str = "test images") -> str:
    """The means table, with each method's worst image against ``reference`` and how many images it leaves more
    than HARM_DB below it (the generalisation issue's two bars: the mean gain, and no image below -HARM_DB); how
    many of the test set's ``noun`` were scored, and the others (``unscored``: name, reason) with the reason."""
    means = method_means(rows)
    images = list(dict.fromkeys(row.image for row in rows))
    lines = [f"# Evaluation\n\n{description}\n\n{len(images)} of {len(images) + len(unscored)} {noun} scored. "
             "Means over images; "
             f"'vs {reference}' is the mean linear-PSNR gain over the row '{reference}' on the images both were "
             f"scored on, 'worst' the least gain of any image, 'below' the count of images more than {HARM_DB} dB "
             f"below '{reference}'.\n",
             f"| method | PSNR linear (dB, peak 2^8) | vs {reference} (dB) | worst vs {reference} (dB) | below | "
             "PU21-PSNR (dB) | PSNR-mu (dB) |",
             "|---|---|---|---|---|---|---|"]
    worst_images = []
    for method, value in means.items():
        pairs = paired_gains(rows, method, reference)
        gain = worst = below = ""
        if pairs:
            gains = np.array([gain_db for _, gain_db in pairs])
            gain, worst, below = f"{gains.mean():+.2f}", f"{gains.min():+.2f}", str(int((gains < -HARM_DB).sum()))
            if method != reference:
                worst_images.append(f"{method}: {min(pairs, key=lambda pair: pair[1])[0]}")
        lines.append(f"| {method} | {value['psnr_linear']:.2f} | {gain} | {worst} | {below} | "
                     f"{value['pu21_psnr']:.2f} | {value['psnr_mu']:.2f} |")
    if worst_images:
        lines.append(f"\nWorst image per method: {'; '.join(worst_images)}.")
    if unscored:
        lines.append(f"\nNot scored ({len(unscored)}):\n")
        lines += [f"- {name}: {reason}" for name, reason in unscored]
    return "\n".join(lines) + "\n"


def examples_figure(examples: list[Example], tile_px: int = 256) -> np.ndarray:
    """Rows of tone-mapped images (truth, then each method), all at the truth's exposure."""
    import cv2

    rows = []
    for example in examples:
        exposure = log_average_luminance(example.truth)
        panels = [("truth", example.truth), *example.outputs.items()]
        tiles = []
        for label, image in panels:
            tile = cv2.resize(tonemap_rgb(image, log_average=exposure), (tile_px, tile_px),
                              interpolation=cv2.INTER_AREA)
            cv2.putText(tile, label, (4, 16), cv2.FONT_HERSHEY_PLAIN, 1.0, (255, 255, 0))
            tiles.append(tile)
        rows.append(np.concatenate(tiles, axis=1))
    return np.concatenate(rows, axis=0)


def write_report(out: Path, rows: list[ScoredImage], examples: list[Example], description: str, *,
                 overwrite: bool = False, unscored: list[tuple[str, str]] = (), noun: str = "test images") -> None:
    """metrics.csv, summary.md and (with examples) examples.jpg in ``out``, published together or not at all;
    ``unscored``, ``noun``: :func:`summary_markdown`'s."""
    paths = [out / "metrics.csv", out / "summary.md"] + ([out / "examples.jpg"] if examples else [])
    with atomic_paths(paths, overwrite=overwrite) as temporaries:
        write_text_atomic(temporaries[0], metrics_csv(rows), overwrite=True)  # an error names the file
        summary = summary_markdown(rows, description, unscored=unscored, noun=noun)
        write_text_atomic(temporaries[1], escaped_name(summary), overwrite=True)  # a folder's name, say
        if examples:
            write_jpeg(temporaries[2], examples_figure(examples), overwrite=True)
