"""Whether a file begins with a format's magic bytes: how a file is known whatever its name."""

from __future__ import annotations

from pathlib import Path


def starts_with(path: Path, magic: bytes) -> bool:
    """True when the file at ``path`` begins with ``magic``."""
    with open(path, "rb") as handle:
        return handle.read(len(magic)) == magic
