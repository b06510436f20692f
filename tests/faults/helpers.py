"""Running commands under faults, and checking what the exit-status contract promises."""

from __future__ import annotations

import contextlib
import hashlib
import os
import resource
from pathlib import Path

from hdrcam.cli import main
from hdrcam.io.atomic import TEMPORARY_SUFFIX


def run(argv: list[str], capsys) -> tuple[int, str, list[str]]:
    """Run ``hdrcam ARGV`` in this process: (exit status, stdout, stderr lines without warnings/progress)."""
    capsys.readouterr()
    try:
        status = main([str(a) for a in argv])
    except SystemExit as exit_:  # argparse
        status = exit_.code
    captured = capsys.readouterr()
    lines = [line for line in captured.err.splitlines()
             if line.strip() and not line.startswith("hdrcam: warning:") and " [" not in line.split(":")[0]
             and "#" not in line]
    return status, captured.out, lines


def assert_failed_with_one_line(result, status: int = 1, *mentions: str) -> str:
    """Exit ``status`` with exactly one error line (no traceback) that names each of ``mentions``."""
    code, _, lines = result
    assert code == status, (code, lines)
    errors = [line for line in lines if "error:" in line or "interrupted" in line]
    assert len(errors) == 1 and not any("Traceback" in line for line in lines), lines
    for mention in mentions:
        assert mention in errors[0], (mention, errors[0])
    return errors[0]


def snapshot(*folders: Path) -> dict[str, str]:
    """sha256 of every file under ``folders`` (names relative to the file system root)."""
    digests = {}
    for folder in folders:
        for root, _, files in os.walk(folder):
            for name in files:
                path = Path(root) / name
                if not path.is_symlink():
                    digests[str(path)] = hashlib.sha256(path.read_bytes()).hexdigest()
    return digests


def temporaries(folder: Path) -> list[Path]:
    """Leftover temporary files of atomic writes under ``folder``."""
    return [p for p in Path(folder).rglob("*") if TEMPORARY_SUFFIX in p.name]


@contextlib.contextmanager
def file_size_limit(limit_bytes: int):
    """RLIMIT_FSIZE for this process: a write past ``limit_bytes`` fails with EFBIG (a full disk, as a process
    sees it; Python ignores SIGXFSZ)."""
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit_bytes, hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
