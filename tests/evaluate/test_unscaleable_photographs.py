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
