"""tools/independent_night_scenes.py: the test-only night scenes are valid linear HDR, reproducible from their
seed, and the tool refuses bad arguments."""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import cv2
import numpy as np
import OpenEXR
import pytest

TOOL = Path(__file__).resolve().parents[2] / "tools" / "independent_night_scenes.py"
sys.path.insert(0, str(TOOL.parent))
from independent_night_scenes import main  # noqa: E402

SEED = 1  # small and cheap: an 'across' and a 'skyline' scene, about 3 s together on one core


def _generate(out: Path, seed: int, count: int) -> list[Path]:
    threads = cv2.getNumThreads()  # the worker sets cv2 to one thread; leave the other tests as they were
    try:
        assert main(["--count", str(count), "--seed", str(seed), "--jobs", "1", "--out", str(out)]) == 0
    finally:
        cv2.setNumThreads(threads)
    return sorted(out.glob("*.exr"))


def _read(path: Path) -> np.ndarray:
    with OpenEXR.File(str(path)) as f:
        channels = f.channels()
        assert list(channels) == ["RGB"]
        return np.array(channels["RGB"].pixels)


@pytest.fixture(scope="module")
def scenes(tmp_path_factory) -> list[Path]:
    return _generate(tmp_path_factory.mktemp("night") / "scenes", SEED, 2)


def test_scenes_are_linear_hdr(scenes, capsys):
    """Two float32 RGB 1024 x 1024 scenes, finite and non-negative, with highlights above 1 and a light source
    (luminance above 10) in at least one; only the EXRs are written (no contact sheet without --contact)."""
    assert [p.name for p in scenes] == ["night-gen-000.exr", "night-gen-001.exr"]
    assert sorted(p.name for p in scenes[0].parent.parent.iterdir()) == ["scenes"]
    peaks = []
    for path in scenes:
        image = _read(path)
        assert image.dtype == np.float32 and image.shape == (1024, 1024, 3)
        assert np.isfinite(image).all() and (image >= 0).all()
        peaks.append((float(image.max()), float((image @ np.float32([0.2126, 0.7152, 0.0722])).max())))
    assert any(peak > 1 for peak, _ in peaks)
    assert any(luminance > 10 for _, luminance in peaks)


def test_same_seed_same_bytes_other_seed_other_scenes(scenes, tmp_path):
    again = _generate(tmp_path / "again", SEED, 2)
    assert [p.read_bytes() for p in again] == [p.read_bytes() for p in scenes]
    other = _generate(tmp_path / "other", SEED + 2, 1)
    assert other[0].read_bytes() != scenes[0].read_bytes()
    assert not np.array_equal(_read(other[0]), _read(scenes[0]))


@pytest.mark.parametrize("option", ["--count", "--jobs"])
@pytest.mark.parametrize("value", ["0", "-1"])
def test_count_or_jobs_below_one_is_a_usage_error(option, value, tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_:
        main([option, value, "--out", str(tmp_path / "scenes")])
    assert exit_.value.code == 2
    assert f"argument {option}: must be at least 1" in capsys.readouterr().err
    assert not (tmp_path / "scenes").exists()


def test_out_that_is_a_file_is_refused_in_one_line(tmp_path, capsys):
    target = tmp_path / "scenes"
    target.write_text("not a folder")
    assert main(["--count", "1", "--out", str(target)]) == 1
    captured = capsys.readouterr()
    assert len(captured.err.strip().splitlines()) == 1 and str(target) in captured.err
    assert captured.out == "" and target.read_text() == "not a folder"


def test_imports_nothing_from_hdrcam():
    """Written without the project's generator, so its scenes test generalisation across generators."""
    imported = set()
    for node in ast.walk(ast.parse(TOOL.read_text())):
        if isinstance(node, ast.Import):
            imported.update(alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            imported.add((node.module or "").split(".")[0])
    assert "hdrcam" not in imported
    assert imported <= {"argparse", "math", "multiprocessing", "os", "sys", "time", "numpy", "cv2", "OpenEXR"}


def test_scenes_already_in_out_are_kept_unless_overwrite(scenes, capsys):
    """A second run into a folder holding its scenes refuses in one line and leaves them as they were."""
    before = [p.read_bytes() for p in scenes]
    assert main(["--count", "2", "--seed", str(SEED + 2), "--jobs", "1", "--out", str(scenes[0].parent)]) == 1
    error = capsys.readouterr().err
    assert len(error.strip().splitlines()) == 1 and "night-gen-000.exr" in error and "--overwrite" in error
    assert [p.read_bytes() for p in scenes] == before
