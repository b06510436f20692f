"""Every command against destinations it cannot use: under a file, read-only, full, already written, a file
appearing while it writes. Each ends with exit 1 and one line, changes no existing byte, leaves no partial file."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from hdrcam.io import atomic
from tests.faults.conftest import COMMANDS, command_lines
from tests.faults.helpers import assert_failed_with_one_line, file_size_limit, run, snapshot, temporaries


@pytest.mark.parametrize("name", COMMANDS + ("demo",))
def test_a_destination_under_a_regular_file_is_refused_with_its_path(name, workspace, tmp_path, capsys):
    blocker = tmp_path / "blocker"
    blocker.write_bytes(b"not a folder")
    out = blocker / "out"
    argv = ["demo", "--out", out] if name == "demo" else command_lines(workspace, out)[name]
    before = snapshot(workspace.root)
    line = assert_failed_with_one_line(run(argv, capsys), 1, str(blocker))
    assert "not a folder" in line
    assert blocker.read_bytes() == b"not a folder" and snapshot(workspace.root) == before


@pytest.mark.parametrize("name", COMMANDS)
def test_a_read_only_destination_is_refused_before_any_work(name, workspace, tmp_path, capsys, monkeypatch):
    folder = tmp_path / "read-only"
    folder.mkdir()
    folder.chmod(0o555)
    if os.geteuid() == 0:  # root may write anyway; the permission check then sees what any user would
        access = os.access
        monkeypatch.setattr(os, "access", lambda path, mode, **options: (
            False if Path(path) == folder and mode & os.W_OK else access(path, mode, **options)))
    try:
        assert_failed_with_one_line(run(command_lines(workspace, folder / "out")[name], capsys), 1, str(folder),
                                    "permission denied")
    finally:
        folder.chmod(0o755)
    assert list(folder.iterdir()) == []


@pytest.mark.parametrize("name", COMMANDS)
def test_a_full_destination_fails_with_one_line_and_leaves_no_partial_file(name, workspace, tmp_path, capsys):
    out = tmp_path / "out"
    before = snapshot(workspace.root)
    with file_size_limit(1024):  # every output of these commands is larger
        result = run(command_lines(workspace, out)[name], capsys)
    assert_failed_with_one_line(result, 1, str(out), "file too large")
    assert temporaries(tmp_path) == [] and snapshot(workspace.root) == before
    for path in out.rglob("*"):  # what was published before the failure is whole, never cut at the limit
        assert not path.is_file() or path.stat().st_size != 1024


@pytest.mark.parametrize("name", COMMANDS)
def test_existing_outputs_are_refused_and_keep_every_byte(name, workspace, tmp_path, capsys):
    out = tmp_path / "out"
    argv = command_lines(workspace, out)[name]
    assert run(argv, capsys)[0] == 0
    written = snapshot(out)
    line = assert_failed_with_one_line(run(argv, capsys), 1, str(out))
    assert "exists" in line or "already holds a run" in line
    assert snapshot(out) == written and temporaries(tmp_path) == []


@pytest.mark.parametrize("name", ("fuse", "reconstruct", "ingest", "capture", "design"))
def test_a_file_appearing_between_check_and_write_is_left_alone(name, workspace, tmp_path, capsys, monkeypatch):
    """Another program creates the output just before it is published: it keeps its bytes, the command fails."""
    intruders = []
    flush = atomic._flush_to_disk

    def someone_else_writes_first(temporary):
        final = temporary.parent / (temporary.name[1:].split(".")[0] + temporary.suffix)
        outermost = temporary.name.count(atomic.TEMPORARY_SUFFIX) == 1  # not one written inside another's temporary
        if not intruders and outermost and not final.exists():
            final.write_bytes(b"another program's file")
            intruders.append(final)
        flush(temporary)

    monkeypatch.setattr(atomic, "_flush_to_disk", someone_else_writes_first)
    out = tmp_path / "out"
    result = run(command_lines(workspace, out)[name], capsys)
    assert intruders, "no output was published"
    assert_failed_with_one_line(result, 1, str(intruders[0]), "appeared while it was being written")
    assert intruders[0].read_bytes() == b"another program's file" and temporaries(tmp_path) == []


def test_overwrite_replaces_whole_files_and_never_an_input(workspace, tmp_path, capsys):
    out = tmp_path / "fused.exr"
    argv = ["fuse", workspace.bracket, "--profile", "simulated", "--out", out]
    assert run(argv, capsys)[0] == 0
    assert run(argv + ["--overwrite"], capsys)[0] == 0
    assert temporaries(tmp_path) == []
    before = snapshot(workspace.root)
    frame = workspace.bracket / "frame-00.dng"
    assert_failed_with_one_line(run(["fuse", workspace.bracket, "--profile", "simulated", "--out", frame,
                                     "--overwrite"], capsys), 1, str(frame), "is also an input")
    assert snapshot(workspace.root) == before


def test_fuse_publishes_its_exr_and_preview_together_or_neither(workspace, tmp_path, capsys, monkeypatch):
    """A preview that fails after the EXR was written (a full disk) leaves no EXR either, so a rerun starts clean."""
    import errno

    import hdrcam.io.png

    def full_disk(image, path="image"):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(hdrcam.io.png, "encoded_png", full_disk)
    out = tmp_path / "fused.exr"
    assert_failed_with_one_line(run(["fuse", workspace.bracket, "--profile", "simulated", "--out", out], capsys),
                                1, "no space")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("name, module, function", [("reconstruct", "hdrcam.preview", "confidence_preview"),
                                                     ("calibrate", "hdrcam.calibrate.record", "radial_profile_plot"),
                                                     ("psf", "hdrcam.preview", "side_by_side"),
                                                     ("fabricate", "hdrcam.cli.fabricate_command", "_markdown"),
                                                     ("destreak", "hdrcam.preview", "display_oriented"),
                                                     ("evaluate", "hdrcam.evaluate.report", "examples_figure")])
def test_a_failure_at_the_last_output_leaves_none_of_the_set(name, module, function, workspace, tmp_path, capsys,
                                                            monkeypatch):
    """reconstruct's EXR and previews of a frame, calibrate's PSF, record and preview, psf's four files, fabricate's
    height map, masks and reports, destreak's EXR and preview, evaluate's report: all, or none."""
    import errno
    import importlib

    def full_disk(*arguments, **options):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(importlib.import_module(module), function, full_disk)
    out = tmp_path / "out"
    assert_failed_with_one_line(run(command_lines(workspace, out)[name], capsys), 1, "no space")
    assert not [path for path in tmp_path.rglob("*") if path.is_file()]


def test_simulate_publishes_its_frame_and_truth_together_or_neither(workspace, tmp_path, capsys, monkeypatch):
    import errno

    import hdrcam.io.exr

    written, write_exr = [], hdrcam.io.exr.write_exr

    def full_at_the_truth(path, *arguments, **options):
        written.append(path)
        if len(written) == 2:
            raise OSError(errno.ENOSPC, "No space left on device")
        return write_exr(path, *arguments, **options)

    monkeypatch.setattr(hdrcam.io.exr, "write_exr", full_at_the_truth)
    assert_failed_with_one_line(run(command_lines(workspace, tmp_path / "out")["simulate"], capsys), 1, "no space")
    assert len(written) == 2 and not [path for path in tmp_path.rglob("*") if path.is_file()]


@pytest.mark.parametrize("argv", [
    lambda ws, t: ["simulate", "night", "--psf", t / "psf.exr", "--size", "32", "32", "--out", t / "psf.exr",
                   "--overwrite"],
    lambda ws, t: ["reconstruct", ws.frame, "--psf", t / "frame.exr", "--out", t, "--overwrite"],
    lambda ws, t: ["evaluate", "--data", ws.root, "--psf", t / "summary.md", "--out", t, "--overwrite"],
])
def test_a_psf_named_as_an_output_is_refused_as_an_input(argv, workspace, tmp_path, capsys):
    """--psf files are inputs: --overwrite never replaces them."""
    command = argv(workspace, tmp_path)
    psf = command[command.index("--psf") + 1]
    psf.write_bytes(workspace.psf.read_bytes())
    assert_failed_with_one_line(run(command, capsys), 1, str(psf), "is also an input")
    assert psf.read_bytes() == workspace.psf.read_bytes()


@pytest.mark.parametrize("target", ["bracket.json", "darks/bracket.json", "darks/dark-00.dng"])
def test_overwrite_never_replaces_a_manifest_or_a_dark_frame(workspace, target, capsys):
    """The bracket's and the darks' manifests and the dark frames are inputs too."""
    before = snapshot(workspace.root)
    destination = workspace.bracket / target
    assert_failed_with_one_line(run(["fuse", workspace.bracket, "--darks", workspace.bracket / "darks", "--profile",
                                     "simulated", "--out", destination, "--overwrite"], capsys),
                                1, str(destination), "is also an input")
    assert snapshot(workspace.root) == before


@pytest.mark.parametrize("argv, mentions", [
    (lambda ws, t: ["fuse", ws.bracket, "--profile", "simulated", "--out", t / "x.png"], ("x.png",)),
    (lambda ws, t: ["simulate", "night", "--psf", "dirac", "--size", "32", "32", "--out", t / "x.exr",
                    "--truth", t / "x.exr"], ("x.exr",)),
    (lambda ws, t: ["reconstruct", ws.frame, t / "copy" / ws.frame.name, "--out", t / "out"], ("frame.exr",)),
])
def test_two_outputs_of_one_command_with_the_same_name_are_refused_before_writing(argv, mentions, workspace,
                                                                                  tmp_path, capsys):
    (tmp_path / "copy").mkdir()
    (tmp_path / "copy" / workspace.frame.name).write_bytes(workspace.frame.read_bytes())
    before = sorted(p.name for p in tmp_path.rglob("*"))
    assert_failed_with_one_line(run(argv(workspace, tmp_path), capsys), 1, *mentions)
    assert sorted(p.name for p in tmp_path.rglob("*")) == before


def test_fuse_publishes_no_preview_when_its_exr_fails(workspace, tmp_path, capsys, monkeypatch):
    """The preview is made while the EXR is written, and published only after it."""
    import errno

    from hdrcam.io import exr

    def disk_full(path, *args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))

    monkeypatch.setattr(exr, "write_exr_channels", disk_full)
    out = tmp_path / "out"
    assert_failed_with_one_line(run(command_lines(workspace, out)["fuse"], capsys), 1, "no space left")
    assert not (out / "fused.png").exists() and not (out / "fused.exr").exists()


def test_fuse_stopped_while_writing_its_exr_leaves_no_output(workspace, tmp_path, capsys, monkeypatch):
    """The EXR is written on the main thread: a signal there discards it unfinished (the preview, made on a
    second thread meanwhile, is never published). Written on a worker, it would be published after the
    command had reported the interrupt, when the interpreter waits for its threads."""
    import signal
    import threading
    import time

    from hdrcam.io import exr

    write = exr.write_exr_channels

    def stopped_while_writing(*args, **kwargs):
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(2)  # the signal handler interrupts this on the main thread
        return write(*args, **kwargs)

    monkeypatch.setattr(exr, "write_exr_channels", stopped_while_writing)
    out = tmp_path / "out"
    assert_failed_with_one_line(run(command_lines(workspace, out)["fuse"], capsys), 128 + signal.SIGTERM, "SIGTERM")
    for thread in threading.enumerate():  # what the interpreter would wait for before the process ends
        if thread.name.startswith("ThreadPoolExecutor"):
            thread.join(timeout=30)
    assert not (out / "fused.png").exists() and not (out / "fused.exr").exists()
    assert temporaries(tmp_path) == []
