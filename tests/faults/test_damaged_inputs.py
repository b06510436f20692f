"""Damaged and adversarial inputs: truncated files, changed frames, darks for lights, mixed cameras, bad pixels,
1 x 1 images, link loops, odd names. Each is refused with exit 1 and one line, or handled (exit 0); never exit 3."""

from __future__ import annotations

import json
import os
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from hdrcam.cli import main
from hdrcam.io.exr import write_exr
from tests.faults.helpers import assert_failed_with_one_line, run, temporaries


def copy_bracket(source: Path, target: Path) -> Path:
    shutil.copytree(source, target)
    return target


def test_a_frame_changed_after_capture_is_refused_by_fuse_and_calibrate_naming_it(workspace, tmp_path, capsys):
    bracket = copy_bracket(workspace.bracket, tmp_path / "bracket")
    frame = bracket / "frame-01.dng"
    data = bytearray(frame.read_bytes())
    data[-100] ^= 0xFF  # one pixel's byte
    frame.write_bytes(bytes(data))
    for argv in (["fuse", bracket, "--profile", "simulated", "--out", tmp_path / "f.exr"],
                 ["calibrate", "psf", bracket, "--profile", "simulated", "--out", tmp_path / "cal"]):
        assert_failed_with_one_line(run(argv, capsys), 1, str(frame), "sha256")
    assert not (tmp_path / "f.exr").exists() and not (tmp_path / "cal").exists()


def test_darks_given_as_lights_and_lights_as_darks_are_refused(workspace, tmp_path, capsys):
    darks = workspace.bracket / "darks"
    assert_failed_with_one_line(run(["fuse", darks, "--profile", "simulated", "--out", tmp_path / "f.exr"], capsys),
                                1, str(darks), "dark frames where light frames are expected")
    assert_failed_with_one_line(run(["fuse", workspace.bracket, "--darks", workspace.bracket, "--profile",
                                     "simulated", "--out", tmp_path / "f.exr"], capsys), 1, "light frames where dark")


def test_darks_of_another_iso_or_camera_are_refused(workspace, tmp_path, capsys):
    """Darks carry the lights' dark current and read noise only at their ISO, from their body."""
    iso_800 = tmp_path / "iso800"
    assert main(["capture", "bracket", "--camera", "sim", "--profile", "simulated", "--psf", "dirac", "--darks",
                 "--size", "64x48", "--stops", "3", "--iso", "800", "--out", str(iso_800)]) == 0
    other_body = copy_bracket(workspace.bracket / "darks", tmp_path / "other-body")
    for frame in other_body.glob("*.dng"):
        frame.write_bytes(frame.read_bytes().replace(b"ILCE-7\0", b"ILCE-9\0"))
    (other_body / "bracket.json").unlink()  # its sha256s no longer hold: the frames as a folder
    capsys.readouterr()
    for darks, mentions in ((iso_800 / "darks", "ISO 800"), (other_body, "ILCE-9")):
        assert_failed_with_one_line(run(["fuse", workspace.bracket, "--darks", darks, "--profile", "simulated",
                                         "--out", tmp_path / "f.exr"], capsys), 1, "dark frames of", mentions)
    assert not (tmp_path / "f.exr").exists()


def test_a_bracket_mixing_two_camera_models_is_refused_naming_the_frame(workspace, tmp_path, capsys):
    other = tmp_path / "frame-02.dng"  # the same frame as if from another body (its Model tag changed)
    data = (workspace.bracket / "frame-02.dng").read_bytes()
    assert b"ILCE-7\0" in data
    other.write_bytes(data.replace(b"ILCE-7\0", b"ILCE-9\0"))
    mixed = [workspace.bracket / "frame-00.dng", workspace.bracket / "frame-01.dng", other]
    assert_failed_with_one_line(run(["fuse", *mixed, "--profile", "simulated", "--out", tmp_path / "f.exr"], capsys),
                                1, "camera model", str(other))


def test_truncated_raw_and_incomplete_manifests_are_refused(workspace, tmp_path, capsys):
    bracket = copy_bracket(workspace.bracket, tmp_path / "bracket")
    frame = bracket / "frame-02.dng"
    frame.write_bytes(frame.read_bytes()[:frame.stat().st_size // 2])
    files = [bracket / "frame-00.dng", bracket / "frame-01.dng", frame]
    assert_failed_with_one_line(run(["fuse", *files, "--profile", "simulated", "--out", tmp_path / "f.exr"], capsys),
                                1, str(frame))
    manifest = json.loads((bracket / "bracket.json").read_text())
    manifest.update(status="incomplete", error="interrupted (SIGTERM)")
    (bracket / "bracket.json").write_text(json.dumps(manifest))
    assert_failed_with_one_line(run(["fuse", bracket, "--profile", "simulated", "--out", tmp_path / "f.exr"], capsys),
                                1, "incomplete", "--resume")


def test_damaged_exr_files_are_refused_by_every_reader(shared_data, tmp_path, capsys):
    damaged = sorted(p for p in (shared_data / "damaged-exr").iterdir() if not p.name.startswith("LICENSE"))
    assert damaged
    for index, path in enumerate(damaged):
        source = tmp_path / f"damaged-{index}.exr"
        shutil.copyfile(path, source)
        for argv in (["reconstruct", source, "--out", tmp_path / f"r{index}"],
                     ["simulate", source, "--psf", "dirac", "--out", tmp_path / f"s{index}.exr"],
                     ["fabricate", source, "--profile", "simulated", "--out", tmp_path / f"f{index}"]):
            assert_failed_with_one_line(run(argv, capsys), 1, str(source))
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"damaged-{i}.exr" for i in range(len(damaged))]


@pytest.mark.parametrize("value, words", [(np.nan, "NaN"), (np.inf, "NaN or Inf"), (-0.5, "down to -0.5")])
def test_frames_with_nan_inf_or_negative_pixels_are_refused(value, words, tmp_path, capsys):
    pixels = np.full((32, 32, 3), 0.25, np.float32)
    pixels[5, 7, 1] = value
    source = tmp_path / "frame.exr"
    write_exr_unchecked(source, pixels)
    for argv in (["reconstruct", source, "--out", tmp_path / "r"], ["destreak", source, "--out", tmp_path / "d"]):
        assert_failed_with_one_line(run(argv, capsys), 1, str(source), words)


def write_exr_unchecked(path: Path, pixels: np.ndarray) -> None:
    """An EXR holding what write_exr refuses to write (NaN, Inf): as another program might."""
    import OpenEXR

    channels = {name: np.ascontiguousarray(pixels[..., i]) for i, name in enumerate("RGB")}
    OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, channels).write(str(path))


def test_a_scene_with_negative_pixels_is_simulated_with_a_warning(tmp_path, capsys):
    scene = np.full((40, 40, 3), 2.0, np.float32)
    scene[3:9, 3:9] = -1.0
    write_exr(tmp_path / "scene.exr", scene)
    with pytest.warns(UserWarning, match="negative .* taken as 0"):
        status, _, _ = run(["simulate", tmp_path / "scene.exr", "--psf", "dirac", "--out", tmp_path / "f.exr"],
                           capsys)
    assert status == 0


def test_a_black_scene_is_refused_naming_the_file(tmp_path, capsys):
    """It said "error: image has no light to scale ..." without the file (every input error names its input)."""
    write_exr(tmp_path / "black.exr", np.zeros((16, 16, 3), np.float32))
    assert_failed_with_one_line(run(["simulate", tmp_path / "black.exr", "--psf", "dirac", "--out", tmp_path / "f.exr"],
                                    capsys), 1, f"{tmp_path / 'black.exr'}: image has no light to scale")


@pytest.mark.parametrize("argv", [
    lambda t: ["reconstruct", t / "one.exr", "--out", t / "out"],
    lambda t: ["destreak", t / "one.exr", "--out", t / "out"],
    lambda t: ["simulate", t / "one.exr", "--psf", "dirac", "--out", t / "out.exr"],
    lambda t: ["fabricate", t / "one.exr", "--profile", "simulated", "--out", t / "out"],
    lambda t: ["capture", "bracket", "--camera", "sim", "--profile", "simulated", "--psf", "dirac",
               "--size", "1x1", "--stops", "1", "--out", t / "out"],
])
def test_one_pixel_images_end_in_success_or_one_line(argv, tmp_path, capsys):
    write_exr(tmp_path / "one.exr", np.full((1, 1, 3), 0.5, np.float32), attributes={"pixel_pitch_m": 32e-6})
    status, _, lines = run(argv(tmp_path), capsys)
    assert status in (0, 1, 2), lines
    if status:
        assert_failed_with_one_line((status, "", lines), status)
    assert temporaries(tmp_path) == []


def test_symlink_loops_as_input_and_output_are_refused(workspace, tmp_path, capsys):
    loop = tmp_path / "loop.exr"
    os.symlink(loop, loop)
    assert_failed_with_one_line(run(["reconstruct", loop, "--out", tmp_path / "r"], capsys), 1, str(loop))
    folder_loop = tmp_path / "folder-loop"
    os.symlink(folder_loop, folder_loop)
    assert_failed_with_one_line(run(["fuse", workspace.bracket, "--profile", "simulated", "--out",
                                     folder_loop / "f.exr"], capsys), 1, str(folder_loop))
    assert_failed_with_one_line(run(["fuse", workspace.bracket, "--profile", "simulated", "--out", loop], capsys),
                                1, str(loop), "exists")
    assert os.readlink(loop) == str(loop)


def test_non_utf8_names_work_and_long_names_are_refused_in_one_line(workspace, tmp_path, capsys):
    odd = Path(os.fsdecode(bytes(tmp_path) + b"/caf\xe9-\xff"))
    odd.mkdir()
    shutil.copyfile(workspace.frame, odd / "frame.exr")
    status, _, lines = run(["reconstruct", odd / "frame.exr", "--out", odd / "out"], capsys)
    assert status == 0 and (odd / "out" / "frame.exr").is_file(), lines
    line = assert_failed_with_one_line(run(["reconstruct", odd / "frame.exr", "--out", odd / "out"], capsys), 1)
    assert "\\udcff" in line or "\\xff" in line  # the name as it is, escaped, on one line
    long_name = tmp_path / ("x" * 300 + ".exr")
    assert_failed_with_one_line(run(["fuse", workspace.bracket, "--profile", "simulated", "--out", long_name],
                                    capsys), 1, "too long")
    newline = tmp_path / "two\nlines"
    line = assert_failed_with_one_line(run(["reconstruct", newline, "--out", tmp_path / "r"], capsys), 1)
    assert "two\\nlines" in line
    assert temporaries(tmp_path) == []


def test_raw_files_with_non_utf8_names_fuse_and_ingest(workspace, tmp_path, capsys):
    """Latin-1 names from a card (rawpy encodes names as UTF-8): read through the file's descriptor."""
    odd = Path(os.fsdecode(bytes(tmp_path) + b"/caf\xe9"))
    odd.mkdir()
    for frame in sorted(workspace.bracket.glob("frame-*.dng")):
        shutil.copyfile(frame, Path(os.fsdecode(bytes(odd) + b"/" + frame.stem.encode() + b"-\xe9.dng")))
    assert run(["fuse", odd, "--profile", "simulated", "--out", tmp_path / "f.exr"], capsys)[0] == 0
    assert run(["ingest", odd, "--out", tmp_path / "manifests"], capsys)[0] == 0


def test_tiny_files_beside_a_bracket_are_skipped_as_not_raw(workspace, tmp_path, capsys):
    """A note shorter than LibRaw's 64-byte header read (it reports an I/O error, as for a damaged file)."""
    folder = copy_bracket(workspace.bracket, tmp_path / "bracket")
    (folder / "bracket.json").unlink()
    shutil.rmtree(folder / "darks")
    (folder / "notes.txt").write_text("tripod, 50mm\n")
    with pytest.warns(UserWarning, match="notes.txt: LibRaw does not open it as RAW"):
        assert run(["fuse", folder, "--profile", "simulated", "--out", tmp_path / "f.exr"], capsys)[0] == 0


def test_several_brackets_at_once_and_repeated_darks_are_refused_saying_why(workspace, tmp_path, capsys):
    for sources, mentions in (([workspace.bracket, workspace.pinholes], "a folder among several inputs"),
                              ([workspace.bracket / "bracket.json", workspace.pinholes / "bracket.json"],
                               "a manifest among several inputs")):
        assert_failed_with_one_line(run(["fuse", *sources, "--profile", "simulated", "--out", tmp_path / "f.exr"],
                                        capsys), 1, str(sources[0]), mentions)
    copies = copy_bracket(workspace.bracket, tmp_path / "copies")
    (copies / "bracket.json").unlink()
    shutil.rmtree(copies / "darks")
    shutil.copyfile(copies / "frame-01.dng", copies / "frame-01 (1).dng")
    assert_failed_with_one_line(run(["fuse", copies, "--profile", "simulated", "--out", tmp_path / "f.exr"], capsys),
                                1, "frame-01 (1).dng: a copy of frame-01.dng")
    darks = copy_bracket(workspace.bracket / "darks", tmp_path / "darks")
    (darks / "bracket.json").unlink()
    second = bytearray((darks / "dark-00.dng").read_bytes())
    second[-100] ^= 1  # another dark at that exposure: one sample differs
    (darks / "dark-00b.dng").write_bytes(bytes(second))
    assert_failed_with_one_line(run(["fuse", workspace.bracket, "--darks", darks, "--profile", "simulated", "--out",
                                     tmp_path / "f.exr"], capsys), 1, "two dark frames", "average repeated darks")


def test_a_frame_given_as_the_psf_is_refused(workspace, tmp_path, capsys):
    """A square frame (its EXR says it holds radiance) is no PSF: normalised, it would have passed as one."""
    for argv in (["simulate", "night", "--size", "32", "32", "--psf", workspace.frame, "--out", tmp_path / "s.exr"],
                 ["reconstruct", workspace.frame, "--psf", workspace.frame, "--out", tmp_path / "r"]):
        assert_failed_with_one_line(run(argv, capsys), 1, str(workspace.frame), "not a PSF")
    assert run(["simulate", "night", "--size", "32", "32", "--psf", workspace.psf, "--out", tmp_path / "s.exr"],
               capsys)[0] == 0


def test_an_empty_folder_to_ingest_is_one_line_on_stderr(tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    status, out, lines = run(["ingest", tmp_path / "empty"], capsys)
    assert_failed_with_one_line((status, out, lines), 1, str(tmp_path / "empty"), "no brackets")
    assert out == ""


def test_a_bug_is_exit_3_in_one_line_and_hdrcam_debug_shows_the_traceback(monkeypatch, capsys):
    from hdrcam.cli import fabricate_command

    def broken(arguments):
        return 1 / 0

    monkeypatch.setattr(fabricate_command, "run", broken)
    status, _, lines = run(["fabricate", "x.exr"], capsys)
    assert status == 3 and len(lines) == 1 and "internal error: ZeroDivisionError" in lines[0]
    monkeypatch.setenv("HDRCAM_DEBUG", "1")
    capsys.readouterr()
    assert main(["fabricate", "x.exr"]) == 3
    assert "Traceback" in capsys.readouterr().err


def test_usage_errors_are_exit_2_in_one_line(capsys):
    status, _, lines = run(["fuse", "--no-such-option"], capsys)
    assert status == 2 and len(lines) == 1


def test_a_full_standard_output_is_exit_1_in_one_line(workspace, tmp_path, capsys, monkeypatch):
    """As `hdrcam ... > /dev/full`: a failed write to stdout is the command's failure (exit 1), not a bug."""
    with open("/dev/full", "w") as full:
        monkeypatch.setattr(sys, "stdout", full)
        status = main(["fabricate", str(workspace.heightmap), "--profile", "simulated", "--out", str(tmp_path / "f")])
    lines = capsys.readouterr().err.strip().splitlines()
    assert status == 1 and len(lines) == 1 and "cannot write to standard output" in lines[0], lines
    assert temporaries(tmp_path) == []


@pytest.mark.parametrize("argv", [["--help"], ["--version"], ["fuse", "--help"]])
def test_help_lost_on_a_full_standard_output_is_exit_1_in_one_line(argv, capsys, monkeypatch):
    """`hdrcam --help > /dev/full`: argparse's own printing is checked as a command's is."""
    with open("/dev/full", "w") as full:
        monkeypatch.setattr(sys, "stdout", full)
        status = main(argv)
    lines = capsys.readouterr().err.strip().splitlines()
    assert status == 1 and len(lines) == 1 and "cannot write to standard output" in lines[0], lines


def test_a_closed_standard_output_is_exit_1_in_one_line(workspace, tmp_path, capsys, monkeypatch):
    """`hdrcam ... >&-`: Python starts with sys.stdout None; writing to it is the command's failure, not a bug."""
    monkeypatch.setattr(sys, "stdout", None)
    status = main(["fabricate", str(workspace.heightmap), "--profile", "simulated", "--out", str(tmp_path / "f")])
    lines = capsys.readouterr().err.strip().splitlines()
    assert status == 1 and len(lines) == 1 and "standard output (it is closed)" in lines[0], lines
    assert temporaries(tmp_path) == []
    monkeypatch.setattr(sys, "stdout", None)
    assert main(["--help"]) == 1


@pytest.mark.parametrize("config, mention", [
    ('{"preset": "fa', "not a readable run configuration"),  # cut short
    ("", "not a readable run configuration"),
    ("[1, 2]", "not a run configuration (a JSON list)"),
    ('{"future_option": 1, "steps": 4, "psf": "psf.exr"}', "settings this hdrcam does not know (future_option)"),
    ('{"learning_rate": null, "psf": "psf.exr"}', "a setting of the wrong type"),
    ('{"weights": [1], "psf": "psf.exr"}', "its loss weights are not a JSON object"),
    ('{"steps": 0, "psf": "psf.exr"}', "steps must be a whole number, 1 or more"),
])
@pytest.mark.parametrize("command", ["design", "finetune"])
def test_a_damaged_or_foreign_run_configuration_is_exit_1_naming_it(command, config, mention, tmp_path, capsys,
                                                                     monkeypatch):
    """A run stopped before its first checkpoint holds config.json alone; damaged, or from a newer hdrcam, it gave
    exit 3, 'internal error: JSONDecodeError ... (a bug; please report it)', without the file."""
    run_folder = tmp_path / "run"
    run_folder.mkdir()
    (run_folder / "config.json").write_text(config)
    (tmp_path / "psf.exr").write_bytes(b"")  # the PSF the foreign run names, where finetune looks for it first
    monkeypatch.chdir(tmp_path)
    assert_failed_with_one_line(run([command, "--out", run_folder, "--resume"], capsys), 1,
                                f"{run_folder / 'config.json'}: {mention}")
