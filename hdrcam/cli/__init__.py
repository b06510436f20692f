"""``hdrcam <command>``: the command line. Bad arguments exit 2 with one line; failures exit 1 with one line."""

from __future__ import annotations

import argparse
import os
import sys
import warnings

from hdrcam import __version__
from hdrcam.errors import HdrcamError


class OneLineParser(argparse.ArgumentParser):
    """An ArgumentParser whose usage errors are a single line (exit status 2)."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see '{self.prog} --help')\n")


def build_parser() -> argparse.ArgumentParser:
    from hdrcam.cli import (calibrate_command, capture_command, demo_command, design_command, destreak_command,
                            evaluate_command, export_command, fabricate_command, fuse_command, ingest_command,
                            inspect_command, psf_command, reconstruct_command, simulate_command)

    parser = OneLineParser(prog="hdrcam", description="Snapshot HDR imaging with a learned rank-1 diffractive "
                                                      "optical element (Sun et al., CVPR 2020).")
    parser.add_argument("--version", action="version", version=f"hdrcam {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="<command>", required=True)
    for module in (psf_command, fabricate_command, capture_command, ingest_command, inspect_command, fuse_command,
                   calibrate_command, design_command, evaluate_command, simulate_command, reconstruct_command,
                   destreak_command, export_command, demo_command):
        module.register(commands)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    arguments = parser.parse_args(argv)
    warnings.formatwarning = lambda message, category, *rest: f"hdrcam: warning: {message}\n"
    try:
        return int(arguments.run(arguments) or 0)
    except HdrcamError as error:
        print(f"hdrcam {arguments.command}: error: {error}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"hdrcam {arguments.command}: interrupted", file=sys.stderr)
        return 130
    except Exception as error:  # never a traceback for users; HDRCAM_DEBUG=1 shows it
        if os.environ.get("HDRCAM_DEBUG"):
            raise
        print(f"hdrcam {arguments.command}: internal error: {type(error).__name__}: {error} "
              "(set HDRCAM_DEBUG=1 for a traceback)", file=sys.stderr)
        return 3


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
