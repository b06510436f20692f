"""A benchmark's markdown report: printed, and written to --out without replacing an existing one unless asked."""

from __future__ import annotations

import argparse
from pathlib import Path

from hdrcam.io.atomic import write_text_atomic


def add_report_options(parser: argparse.ArgumentParser, default_out: str) -> None:
    """--out (default ``default_out``) and --overwrite."""
    parser.add_argument("--out", type=Path, default=Path(default_out), help=f"report (default {default_out})")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing report")


def publish(arguments: argparse.Namespace, lines: list[str]) -> None:
    """Print the report and write it atomically to --out."""
    text = "\n".join(lines) + "\n"
    print(text)
    arguments.out.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(arguments.out, text, overwrite=arguments.overwrite)
