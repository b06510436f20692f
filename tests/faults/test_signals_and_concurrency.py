"""Captures stopped by SIGTERM, SIGINT, a full disk or a refusal, and resumed; two captures started at once into one
folder (processes)."""

from __future__ import annotations

import errno
import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from hdrcam.capture.manifest import MANIFEST_NAME, load_bracket, sha256_of
from tests.faults.helpers import assert_failed_with_one_line, run, temporaries

LONG_CAPTURE = ["capture", "bracket", "--camera", "sim", "--profile", "simulated", "--psf", "dirac", "--size",
                "512x384", "--stops", "24", "--ev-step", "1/3"]


def start(argv: list, **options) -> subprocess.Popen:
    environment = dict(os.environ, OMP_NUM_THREADS="1")
    return subprocess.Popen([sys.executable, "-m", "hdrcam", *map(str, argv)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=environment, **options)


def frames_listed(folder: Path) -> int:
    try:
        return len(json.loads((folder / MANIFEST_NAME).read_text())["frames"])
    except (OSError, ValueError, KeyError):
        return 0


def run_and_signal_after_two_frames(argv: list, folder: Path, number: int, capsys) -> tuple[int, str, list[str]]:
    """Run ``hdrcam ARGV`` here and send this process ``number`` once the manifest lists two frames. Until
    main() installs its handlers, and after it restores them, the signal is ignored (never stops pytest)."""
    sent = threading.Event()

    def signal_when_two_frames_are_listed():
        deadline = time.monotonic() + 60
        while frames_listed(folder) < 2 and time.monotonic() < deadline:
            time.sleep(0.01)
        os.kill(os.getpid(), number)
        sent.set()

    previous = signal.signal(number, signal.SIG_IGN)
    try:
        thread = threading.Thread(target=signal_when_two_frames_are_listed)
        thread.start()
        result = run(argv, capsys)
        thread.join()
    finally:
        signal.signal(number, previous)
    assert sent.is_set()
    return result


def assert_every_frame_on_disk_is_listed(folder: Path) -> None:
    bracket = load_bracket(folder)
    on_disk = sorted(p.name for p in folder.iterdir() if p.suffix == ".dng")
    assert sorted(frame.file for frame in bracket.frames) == on_disk
    assert all(sha256_of(folder / frame.file) == frame.sha256 for frame in bracket.frames)
    assert temporaries(folder) == []


@pytest.mark.parametrize("number", [signal.SIGTERM, signal.SIGINT])
def test_a_stopped_capture_lists_every_frame_and_resumes_to_a_complete_bracket(number, tmp_path, capsys):
    out = tmp_path / "bracket"
    result = run_and_signal_after_two_frames(LONG_CAPTURE + ["--out", out], out, number, capsys)
    assert_failed_with_one_line(result, 128 + number, signal.Signals(number).name)
    bracket = load_bracket(out)
    assert bracket.status == "incomplete" and signal.Signals(number).name in bracket.error
    assert len(bracket.frames) >= 2
    assert_every_frame_on_disk_is_listed(out)
    kept = {frame.file: frame.sha256 for frame in bracket.frames}

    other_plan = LONG_CAPTURE[:-4] + ["--stops", "23", "--ev-step", "1/3", "--resume", "--out", out]
    assert_failed_with_one_line(run(other_plan, capsys), 1, str(out / MANIFEST_NAME), "plan")
    assert_failed_with_one_line(run(LONG_CAPTURE + ["--out", out], capsys), 1, "--resume")  # never overwritten
    assert run(LONG_CAPTURE + ["--resume", "--out", out], capsys)[0] == 0
    bracket = load_bracket(out)
    assert bracket.status == "complete" and len(bracket.frames) == 24
    assert all(frame.sha256 == kept[frame.file] for frame in bracket.frames if frame.file in kept)
    assert_every_frame_on_disk_is_listed(out)


def test_two_captures_started_at_once_into_one_folder_never_mix_or_overwrite(tmp_path):
    out = tmp_path / "bracket"
    argv = LONG_CAPTURE[:-5] + ["64x48", "--stops", "3", "--out", out]
    first, second = start(argv), start(argv + ["--seed", "1"])
    results = [(p.wait(timeout=120), p.stderr.read()) for p in (first, second)]
    statuses = sorted(status for status, _ in results)
    assert statuses == [0, 1], results
    refusal = next(stderr for status, stderr in results if status == 1)
    assert len(refusal.strip().splitlines()) == 1 and str(out / MANIFEST_NAME) in refusal
    bracket = load_bracket(out)
    assert bracket.status == "complete" and len(bracket.frames) == 3
    assert_every_frame_on_disk_is_listed(out)


def test_a_disk_failure_mid_capture_leaves_a_manifest_listing_the_frames_taken(tmp_path, capsys, monkeypatch):
    from hdrcam.capture.simulated import SimulatedCamera

    capture, calls = SimulatedCamera.capture, []

    def disk_full_on_the_second_frame(self, folder, stem, *, dark=False):
        calls.append(stem)
        if len(calls) == 2:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(folder / f"{stem}.dng"))
        return capture(self, folder, stem, dark=dark)

    monkeypatch.setattr(SimulatedCamera, "capture", disk_full_on_the_second_frame)
    out = tmp_path / "bracket"
    argv = LONG_CAPTURE[:-5] + ["64x48", "--stops", "3", "--out", out]
    assert_failed_with_one_line(run(argv, capsys), 1, str(out / "frame-01.dng"), "no space left")
    bracket = load_bracket(out)
    assert bracket.status == "incomplete" and "no space left" in bracket.error
    assert [frame.file for frame in bracket.frames] == ["frame-00.dng"]
    assert_every_frame_on_disk_is_listed(out)


def test_a_capture_refused_part_way_keeps_and_lists_its_frames(tmp_path, capsys, monkeypatch):
    """A frame the camera sends that --auto cannot use (here: one of another size than the region of interest
    was checked against before the first shot) stops the bracket after that frame."""
    import hdrcam.capture.bracket
    from hdrcam.errors import InputError

    def another_size(*arguments):
        raise InputError("--roi 0,0,10,10 reaches past the 8 x 8 px frame the camera sent")

    monkeypatch.setattr(hdrcam.capture.bracket, "frame_statistics", another_size)
    out = tmp_path / "bracket"
    argv = LONG_CAPTURE[:-5] + ["64x48", "--stops", "3", "--auto", "--roi", "0,0,10,10", "--out", out]
    assert_failed_with_one_line(run(argv, capsys), 1, "reaches past")
    bracket = load_bracket(out)
    assert bracket.status == "incomplete" and "reaches past" in bracket.error and len(bracket.frames) == 1
    assert_every_frame_on_disk_is_listed(out)


def test_a_frame_written_just_before_the_interrupt_is_listed(tmp_path, capsys, monkeypatch):
    """SIGINT after the camera wrote frame-01 but before the bracket recorded it: the manifest still lists it."""
    from hdrcam.capture.simulated import SimulatedCamera

    capture = SimulatedCamera.capture

    def interrupted_after_the_second_write(self, folder, stem, *, dark=False):
        frame = capture(self, folder, stem, dark=dark)
        if stem == "frame-01":
            raise KeyboardInterrupt
        return frame

    monkeypatch.setattr(SimulatedCamera, "capture", interrupted_after_the_second_write)
    out = tmp_path / "bracket"
    argv = LONG_CAPTURE[:-5] + ["64x48", "--stops", "3", "--out", out]
    assert_failed_with_one_line(run(argv, capsys), 130, "interrupted")
    bracket = load_bracket(out)
    assert [frame.file for frame in bracket.frames] == ["frame-00.dng", "frame-01.dng"]
    assert any("frame-01.dng was written as the capture stopped" in note for note in bracket.notes)
    assert_every_frame_on_disk_is_listed(out)
