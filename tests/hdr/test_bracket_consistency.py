"""fuse against brackets whose frames disagree with each other: a frame whose data contradict its exposure is
refused."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tests.faults.helpers import assert_failed_with_one_line, run
from tests.io.realistic_dng import sensor_dn, write_dng

EXPOSURES_S = (0.001, 0.004, 0.016, 0.064)
SHAPE = (64, 96)


def _radiance() -> np.ndarray:
    """DN per second above black: a ramp over four decades along the rows, so every pair of frames shares
    unclipped pixels with signal."""
    columns = np.logspace(3, 7, SHAPE[1])
    return np.tile(columns, (SHAPE[0], 1)) * np.linspace(0.8, 1.2, SHAPE[0])[:, None]


def _bracket(folder: Path, **tags) -> list[Path]:
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(3)
    return [write_dng(folder / f"f{k}.dng", sensor_dn(_radiance(), t, rng), exposure_s=t, **tags)
            for k, t in enumerate(EXPOSURES_S)]


def _fuse(frames: list[Path], out: Path, capsys) -> tuple[int, str, list[str]]:
    return run(["fuse", *frames, "--profile", "simulated", "--out", out], capsys)


@pytest.mark.parametrize("black", [0, 1, 2, 3])
def test_a_frame_that_recorded_no_light_is_refused_naming_it(tmp_path, capsys, black):
    """A frame holding only the black level (a capped lens, a failed shutter) among lit ones was merged with full
    weight: the longer frame 'no brighter (ratio 0.0000)' or the shorter one's 'no signal above black' only noted,
    and the output a fraction of the radiance."""
    frames = _bracket(tmp_path / "lit")
    frames[black] = write_dng(tmp_path / f"black-{black}.dng", np.full(SHAPE, 512, np.uint16),
                              exposure_s=EXPOSURES_S[black])
    out = tmp_path / "fused.exr"
    error = assert_failed_with_one_line(_fuse(frames, out, capsys), 1, f"{frames[black]}: ",
                                        "remove it from the bracket")
    assert ("no brighter" if black else "no signal above black") in error
    assert not out.exists() and not out.with_suffix(".png").exists()


def test_a_bracket_of_consistent_frames_still_fuses(tmp_path, capsys):
    out = tmp_path / "fused.exr"
    status, _, lines = _fuse(_bracket(tmp_path / "lit"), out, capsys)
    assert status == 0 and out.exists(), lines
