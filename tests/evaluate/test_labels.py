"""Checkpoint labels of `hdrcam evaluate`: each names one row of the tables, never two."""

from __future__ import annotations

from pathlib import Path

from hdrcam.cli import main

TABLE2 = Path(__file__).resolve().parents[2] / "hdrcam" / "checkpoints" / "table2"


def test_a_label_that_is_another_label_s_network_row_is_refused(tmp_path, capsys):
    """LABEL-network holds LABEL's network alone: a checkpoint labelled so would overwrite that row."""
    status = main(["evaluate", "--data", str(tmp_path), "--checkpoint", f"x-network={TABLE2 / 'dirac.pt'}",
                   "--checkpoint", f"x={TABLE2 / 'star.pt'}", "--out", str(tmp_path / "out")])
    error = capsys.readouterr().err.strip()
    assert status == 1 and error.count("\n") == 0 and "'x-network'" in error and "network alone" in error
    assert not (tmp_path / "out").exists()
