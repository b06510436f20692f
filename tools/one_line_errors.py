"""Run a tool's ``main`` the way ``hdrcam`` runs a command: a failure a user can act on (a missing, unreadable
or damaged input, a refused overwrite: HdrcamError or OSError) is one line on stderr and exit status 1."""

from __future__ import annotations

import sys
from pathlib import Path

from hdrcam.errors import HdrcamError


def run(main) -> int:
    """``main()`` -> its exit status; HdrcamError / OSError -> one line naming the tool, status 1."""
    try:
        return int(main() or 0)
    except (HdrcamError, OSError) as error:
        print(f"{Path(sys.argv[0]).name}: error: {error}", file=sys.stderr)
        return 1


def refuse_existing(path: Path, overwrite: bool) -> None:
    """Before the work: a tool replaces an existing output only when asked (FileExistsError, one line)."""
    if path.exists() and not overwrite:
        raise FileExistsError(f"{path} exists; pass --overwrite to replace it")
