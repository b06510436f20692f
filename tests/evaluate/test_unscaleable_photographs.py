"""Photographs the protocol cannot scale (1.5 % of pixels above 1) are left out of the scores, with a warning."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from hdrcam.cli import main
from hdrcam.io.exr import write_exr


def test_a_uniform_photograph_is_not_scored_and_alone_is_an_error(tmp_path, capsys):
    data = tmp_path / "data"
    data.mkdir()
    write_exr(data / "uniform.exr", np.full((96, 96, 3), 0.5, np.float32))
    argv = ["evaluate", "--data", str(data), "--size", "64", "--no-partner"]
    assert main(argv + ["--out", str(tmp_path / "alone")]) == 1
    assert "nothing scored" in capsys.readouterr().err and not (tmp_path / "alone").exists()
    write_exr(data / "lamps.exr", np.random.default_rng(0).lognormal(0.0, 1.5, (96, 96, 3)).astype(np.float32))
    with pytest.warns(UserWarning, match="uniform: not scored"):
        assert main(argv + ["--out", str(tmp_path / "both")]) == 0
    with open(tmp_path / "both" / "metrics.csv") as table:
        assert {row["image"] for row in csv.DictReader(table)} == {"lamps"}


def test_warnings_have_lines_of_their_own_and_a_tiny_photograph_gets_one(tmp_path):
    """Warnings ran on from the progress bar's line ('...0/3 [00:00<?, ?image/s]hdrcam: warning: ...'), and a
    1 x 1 px photograph was both 'mirrored ... and the mirrored copies are scored too' and 'not scored'."""
    import re
    import subprocess
    import sys

    data = tmp_path / "data"
    data.mkdir()
    write_exr(data / "tiny.exr", np.full((1, 1, 3), 2.0, np.float32))  # mirrored: uniform, cannot be scaled
    write_exr(data / "small.exr", np.random.default_rng(1).lognormal(0.0, 1.5, (40, 40, 3)).astype(np.float32))
    write_exr(data / "lamps.exr", np.random.default_rng(0).lognormal(0.0, 1.5, (96, 96, 3)).astype(np.float32))
    (data / "gone.exr").symlink_to(data / "nonexist.exr")
    done = subprocess.run([sys.executable, "-m", "hdrcam", "evaluate", "--data", str(data), "--size", "64",
                           "--no-partner", "--out", str(tmp_path / "out")],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    pieces = re.split(r"[\r\n]", done.stderr)
    warned = [piece for piece in pieces if "warning" in piece]
    assert warned and all(piece.startswith("hdrcam: warning: ") for piece in warned), warned
    assert [piece for piece in warned if "tiny" in piece] == [
        "hdrcam: warning: tiny: not scored - scaled as the protocol asks, 0 % of its pixels exceed 1, not the 1.5 % "
        "asked (a plateau at its brightest - saturated at source, or uniform - or about as few lit pixels as asked)"]
    assert [piece for piece in warned if "small" in piece] == [
        f"hdrcam: warning: {data / 'small.exr'}: 40 x 40 px, smaller than the 64 px test crop: mirrored to fill it, "
        "and the mirrored copies are scored too"]
    assert [piece for piece in warned if "gone" in piece] == [
        f"hdrcam: warning: {data / 'gone.exr'}: not evaluated - no such file"]
    with open(tmp_path / "out" / "metrics.csv") as table:
        assert {row["image"] for row in csv.DictReader(table)} == {"lamps", "small"}
