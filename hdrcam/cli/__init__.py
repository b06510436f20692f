"""``hdrcam <command>``: the command line. Bad arguments exit 2 with one line; failures exit 1 with one line."""

from __future__ import annotations

import argparse
import importlib
import os
import sys
import warnings

from hdrcam import __version__
from hdrcam.errors import HdrcamError


class OneLineParser(argparse.ArgumentParser):
    """An ArgumentParser whose usage errors are a single line (exit status 2)."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see '{self.prog} --help')\n")


# command -> the module under hdrcam.cli that registers it, in the order of ``hdrcam --help``. Only the module of
# the command being run is imported (all of them for ``hdrcam --help``); none imports torch before its run().
COMMAND_MODULES = {"psf": "psf_command", "fabricate": "fabricate_command", "capture": "capture_command",
                   "ingest": "ingest_command", "fuse": "fuse_command", "calibrate": "calibrate_command",
                   "design": "design_command", "finetune": "design_command", "evaluate": "evaluate_command",
                   "simulate": "simulate_command", "reconstruct": "reconstruct_command",
                   "destreak": "destreak_command", "export": "export_command", "demo": "demo_command"}


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The parser of ``hdrcam``; with a known ``command``, registering only that command's module."""
    parser = OneLineParser(prog="hdrcam", description="Snapshot HDR imaging with a learned rank-1 diffractive "
                                                      "optical element (Sun et al., CVPR 2020).")
    parser.add_argument("--version", action="version", version=f"hdrcam {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="<command>", required=True)
    modules = [COMMAND_MODULES[command]] if command in COMMAND_MODULES else COMMAND_MODULES.values()
    for module in dict.fromkeys(modules):
        importlib.import_module(f"hdrcam.cli.{module}").register(commands)
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    parser = build_parser(next((word for word in argv if not word.startswith("-")), None))
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
