"""The command line's plumbing: HDRCAM_DEBUG's values, and a standard output whose reader has gone (| head)."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from hdrcam.cli import main
from hdrcam.io.exr import read_exr


@pytest.fixture(scope="module")
def bracket(tmp_path_factory):
    folder = tmp_path_factory.mktemp("plumbing") / "bracket"
    assert main(["capture", "bracket", "--camera", "sim", "--profile", "simulated", "--psf", "dirac", "--size",
                 "64x48", "--stops", "3", "--out", str(folder)]) == 0
    return folder


def _bug(arguments):
    return 1 / 0


@pytest.mark.parametrize("value", ["0", "", "false", "No", "OFF", " off "])
def test_hdrcam_debug_off_values_show_no_traceback(value, tmp_path, monkeypatch, capsys):
    from hdrcam.cli import fabricate_command

    monkeypatch.setattr(fabricate_command, "run", _bug)
    monkeypatch.setenv("HDRCAM_DEBUG", value)
    assert main(["fabricate", "x.exr"]) == 3
    assert main(["fuse", str(tmp_path / "nonexist"), "--out", str(tmp_path / "z.exr")]) == 1
    error = capsys.readouterr().err
    assert "Traceback" not in error and error.count("\n") == 2, error


@pytest.mark.parametrize("value", ["1", "yes", "true", "on"])
def test_hdrcam_debug_on_values_show_the_traceback(value, monkeypatch, capsys):
    from hdrcam.cli import fabricate_command

    monkeypatch.setattr(fabricate_command, "run", _bug)
    monkeypatch.setenv("HDRCAM_DEBUG", value)
    assert main(["fabricate", "x.exr"]) == 3
    assert "Traceback" in capsys.readouterr().err


def _closed_pipe() -> int:
    """The write end of a pipe whose reader has already exited, as `hdrcam ... | head -0` gives."""
    read_end, write_end = os.pipe()
    os.close(read_end)
    return write_end


def test_fuse_into_a_closed_pipe_keeps_its_outputs_and_says_so_in_one_line(bracket, tmp_path, monkeypatch, capsys):
    out = tmp_path / "x.exr"
    with os.fdopen(_closed_pipe(), "w") as pipe:
        monkeypatch.setattr(sys, "stdout", pipe)
        status = main(["fuse", str(bracket), "--profile", "simulated", "--out", str(out)])
    lines = capsys.readouterr().err.strip().splitlines()
    assert status == 1 and len(lines) == 1, lines
    assert lines[0].startswith("hdrcam fuse: error: standard output closed early (broken pipe")
    assert "room" not in lines[0]
    assert read_exr(out).rgb().shape == (48, 64, 3) and out.with_suffix(".png").stat().st_size > 0


def test_inspect_into_a_closed_pipe_exits_1_with_one_line_and_no_second_error_at_exit(bracket):
    pipe = _closed_pipe()
    try:
        done = subprocess.run([sys.executable, "-m", "hdrcam", "inspect", *map(str, sorted(bracket.glob("*.dng")))],
                              stdout=pipe, stderr=subprocess.PIPE, text=True, timeout=120)
    finally:
        os.close(pipe)
    assert done.returncode == 1 and done.stderr.count("\n") == 1, done.stderr
    assert done.stderr.startswith("hdrcam inspect: error: standard output closed early (broken pipe")


def test_runtime_errors_name_the_command_with_its_action_as_usage_errors_do(tmp_path, capsys):
    assert main(["capture", "bracket", "--size", "64x48", "--psf", "dirac", "--stops", "100",
                 "--out", str(tmp_path / "b")]) == 1
    assert capsys.readouterr().err.startswith("hdrcam capture bracket: error: 100 exposures")


def _import_interrupted(arguments):
    try:
        raise KeyboardInterrupt  # as Ctrl-C landing inside an extension module's initialisation
    except KeyboardInterrupt:
        raise ImportError("initialization of _C raised unreported exception") from None


def test_an_interrupt_that_an_import_turned_into_an_import_error_is_an_interrupt(monkeypatch, capsys):
    from hdrcam.cli import fabricate_command

    monkeypatch.setattr(fabricate_command, "run", _import_interrupted)
    assert main(["fabricate", "x.exr"]) == 130  # it was reported as an internal error, exit 3
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and "interrupted by SIGINT" in error


def test_a_reported_line_starts_its_own_line_beside_a_progress_bar(capsys):
    import re

    from tqdm import tqdm

    from hdrcam.cli import _report

    with tqdm(total=10, file=sys.stderr, desc="design run") as bar:
        bar.update()
        _report("hdrcam design: interrupted by SIGINT")
    pieces = re.split(r"[\r\n]", capsys.readouterr().err)  # it followed the bar on the bar's own line
    assert "hdrcam design: interrupted by SIGINT" in pieces


def _disk_full_while_cleaning_up(arguments):
    try:
        raise KeyboardInterrupt
    except KeyboardInterrupt:
        raise OSError(28, "No space left on device")


def test_an_error_raised_while_an_interrupt_was_handled_is_reported_as_itself(monkeypatch, capsys):
    from hdrcam.cli import fabricate_command

    monkeypatch.setattr(fabricate_command, "run", _disk_full_while_cleaning_up)
    assert main(["fabricate", "x.exr"]) == 1  # not 130 'interrupted ... outputs removed'
    assert "no space left on the device" in capsys.readouterr().err


def test_fuse_with_standard_output_closed_is_refused_before_any_work(bracket, tmp_path, monkeypatch, capsys):
    """`hdrcam fuse ... >&-` merged the bracket and published X.exr and X.png, then exited 1 at its summary."""
    out = tmp_path / "x.exr"
    monkeypatch.setattr(sys, "stdout", None)  # what Python starts with when descriptor 1 is closed
    assert main(["fuse", str(bracket), "--profile", "simulated", "--out", str(out)]) == 1
    assert capsys.readouterr().err == ("hdrcam fuse: error: cannot write to standard output (it is closed); "
                                       "redirect it to a file or /dev/null\n")
    assert sorted(tmp_path.iterdir()) == []


def test_reconstruct_with_standard_output_closed_is_refused_before_any_work(tmp_path, monkeypatch, capsys):
    """`hdrcam reconstruct ... >&-` reconstructed and wrote the frame's three files, then exited 1."""
    import numpy as np

    from hdrcam.io.exr import write_exr

    frame = tmp_path / "frame.exr"
    write_exr(frame, np.random.default_rng(0).uniform(0.0, 1.0, (48, 64, 3)).astype(np.float32))
    monkeypatch.setattr(sys, "stdout", None)
    assert main(["reconstruct", str(frame), "--no-partner", "--out", str(tmp_path / "out")]) == 1
    assert capsys.readouterr().err == ("hdrcam reconstruct: error: cannot write to standard output (it is closed); "
                                       "redirect it to a file or /dev/null\n")
    assert not (tmp_path / "out").exists()


def _interrupted_by_sigint(arguments):
    from hdrcam.errors import Interrupted

    raise Interrupted(2)


@pytest.mark.parametrize("stop", [_interrupted_by_sigint, _import_interrupted])
def test_an_interrupted_demo_says_demo_and_the_step_it_was_in(stop, tmp_path, monkeypatch, capsys):
    """Its one line named the inner command ('hdrcam capture bracket: interrupted ...'), one the user did not type."""
    from hdrcam.cli import capture_command

    monkeypatch.setattr(capture_command, "run", stop)  # the demo's first step
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--size", "64", "64", "--finetune-steps", "0"]) == 130
    assert capsys.readouterr().err == ("hdrcam demo: interrupted by SIGINT in its step 'capture calibration bracket'; "
                                       "outputs not finished were removed\n")
    assert sorted(path.name for path in out.iterdir()) == ["design-psf.exr"]  # written before the step, kept
