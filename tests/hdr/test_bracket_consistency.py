"""fuse against brackets whose frames disagree with each other: a frame whose data contradict its exposure is
refused; a missing ISO and differing as-shot whites are warned about (they set the scale and the colours)."""

from __future__ import annotations

import warnings
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


def _warnings_of_fuse(frames: list[Path], out: Path, capsys, about: str) -> list[str]:
    """fuse (it must succeed): the warnings that mention ``about``."""
    with warnings.catch_warnings(record=True) as warned:
        warnings.simplefilter("always")
        assert _fuse(frames, out, capsys)[0] == 0 and out.exists()
    return [str(warning.message) for warning in warned if about in str(warning.message)]


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


def test_a_bracket_without_iso_is_fused_at_iso_100_with_a_warning(tmp_path, capsys):
    """No ISO in the files: ISO 100 was assumed silently, though the unit (full wells per second at ISO 100)
    scales with it."""
    frames = _bracket(tmp_path / "noiso", iso=None)
    assert _warnings_of_fuse(frames, tmp_path / "f.exr", capsys, "ISO") == [
        "f0.dng and the bracket's other frames: no ISO recorded; ISO 100 is assumed, and the radiance (full wells "
        "per second at ISO 100) scales with it: frames shot at ISO 400 would read 4x too bright"]
    assert _warnings_of_fuse(_bracket(tmp_path / "iso"), tmp_path / "g.exr", capsys, "ISO") == []


@pytest.mark.parametrize("odd", [0, 2])
def test_frames_of_differing_as_shot_whites_are_warned_about(tmp_path, capsys, odd):
    """The colours follow the shortest frame's as-shot white; another frame's was never compared."""
    frames = _bracket(tmp_path / "wb")
    rng = np.random.default_rng(3)
    frames[odd] = write_dng(tmp_path / f"auto-{odd}.dng", sensor_dn(_radiance(), EXPOSURES_S[odd], rng),
                            exposure_s=EXPOSURES_S[odd], as_shot_neutral=(0.3, 1.0, 0.6))
    others = ", ".join(path.name for k, path in enumerate(frames) if k != odd)
    groups = [f"auto-{odd}.dng: 0.3 1 0.6", f"{others}: 0.5 1 0.7"]
    whites = "; ".join(groups if odd == 0 else groups[::-1])  # in frame order, the shortest frame's first
    assert _warnings_of_fuse(frames, tmp_path / "f.exr", capsys, "white") == [
        f"the frames' as-shot whites (camera RGB) differ ({whites}; auto white balance between shots?): the colours "
        f"follow {frames[0].name}'s, the shortest frame's"]
    # one white, written with other rounding: no warning
    frames[odd] = write_dng(tmp_path / f"auto-{odd}.dng", sensor_dn(_radiance(), EXPOSURES_S[odd], rng),
                            exposure_s=EXPOSURES_S[odd], as_shot_neutral=(0.50003, 1.0, 0.69998))
    assert _warnings_of_fuse(frames, tmp_path / "g.exr", capsys, "white") == []
