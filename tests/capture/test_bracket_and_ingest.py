"""Brackets (fixed, auto, darks, failures) and RAW ingest into bracket manifests."""

from __future__ import annotations

import datetime as dt
import json

import numpy as np
import pytest

from hdrcam.capture.bracket import BracketCapture, BracketPlan
from hdrcam.capture.ingest import ingest_folder
from hdrcam.capture.manifest import load_bracket, sha256_of
from hdrcam.capture.notches import nearest_shutter
from hdrcam.capture.ptp.transport import Disconnected
from hdrcam.cli import main
from hdrcam.errors import InputError
from hdrcam.io.raw import read_raw, read_raw_metadata
from hdrcam.profiles import load_profile
from tests.capture.helpers import small_camera

SPEC = load_profile("simulated").camera


def shoot(kind, folder, plan, scene="flat:0.5", **camera_options):
    camera, simulated = small_camera(kind, scene=scene, **camera_options)
    with camera:
        capture = BracketCapture(camera, SPEC, folder, backend=kind, profile="simulated", show_progress=False,
                                 true_exposure_s=simulated.true_exposure_s)
        return capture.shoot(plan)


def test_sim_and_sim_usb_brackets_hold_identical_raw_data_3_ev_apart(tmp_path):
    plan = BracketPlan(shortest_s=1 / 4000, stops=5, ev_step=3.0)
    brackets = {kind: shoot(kind, tmp_path / kind, plan, scene="night") for kind in ("sim", "sim-usb")}
    for a, b in zip(brackets["sim"].paths(), brackets["sim-usb"].paths()):
        raw_a, raw_b = read_raw(a), read_raw(b)
        assert np.array_equal(raw_a.bayer_dn, raw_b.bayer_dn)
        assert raw_a.metadata.black_level_dn == (512.0,) * 4 and raw_a.metadata.white_level_dn == SPEC.white_level_dn
    frames = load_bracket(tmp_path / "sim-usb").frames
    assert np.allclose(np.diff(np.log2([f.true_exposure_s for f in frames])), 3.0, atol=0.06)  # 2 % notch error
    assert np.allclose(np.diff(np.log2([f.exposure_s for f in frames])), 3.0, atol=0.11)  # rounded labels
    sim = load_bracket(tmp_path / "sim")
    assert all(sha256_of(path) == frame.sha256 for path, frame in zip(sim.paths(), sim.frames))


def test_failed_capture_keeps_complete_frames_and_a_manifest_that_says_why(tmp_path):
    plan = BracketPlan(shortest_s=1 / 4000, stops=3, ev_step=3.0)
    camera, _ = small_camera("sim-usb")
    with camera:
        emulator = camera.session.transport.device._ctx.backend.camera
        capture = BracketCapture(camera, SPEC, tmp_path, backend="sim-usb", profile="simulated", show_progress=False)
        emulator.faults.disconnect_during_download = False
        original = emulator._op_1009

        def second_download_disconnects(request, payload, calls=[]):
            calls.append(1)
            emulator.faults.disconnect_during_download = len(calls) == 2
            return original(request, payload)

        emulator._op_1009 = second_download_disconnects
        with pytest.raises(Disconnected):
            capture.shoot(plan)
    manifest = json.loads((tmp_path / "bracket.json").read_text())
    assert manifest["status"] == "incomplete" and "disconnected" in manifest["error"]
    assert [f["file"] for f in manifest["frames"]] == ["frame-00.dng"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bracket.json", "frame-00.dng"]


def test_auto_stops_once_the_longest_frame_reaches_the_snr_target(tmp_path):
    plan = BracketPlan(shortest_s=1 / 4000, stops=5, ev_step=3.0, auto=True, target_snr=20.0)
    bracket = shoot("sim", tmp_path, plan, scene="flat:0.5", hot_pixel_fraction=0.0)
    # 0.5 x 1/4096 s / (1/60 s) of 25000 e is ~180 e (SNR 13); 8x longer gives ~1500 e (SNR 38)
    assert [f.exposure_label for f in bracket.frames] == ["1/4000", "1/500"]
    assert "auto: 2 frames" in bracket.notes[-1]


def test_auto_goes_shorter_while_the_roi_clips_and_says_when_it_cannot(tmp_path):
    plan = BracketPlan(shortest_s=1 / 60, stops=5, ev_step=3.0, auto=True, roi=(8, 8, 16, 16))
    bracket = shoot("sim", tmp_path / "a", plan, scene="flat:3")
    assert bracket.frames[0].exposure_label == "1/500"  # 1/60 clips at 3x full well, 1/500 does not
    blinding = BracketPlan(shortest_s=1 / 4000, stops=5, ev_step=3.0, auto=True)
    bracket = shoot("sim", tmp_path / "b", blinding, scene="flat:1e5")
    # 3 EV shorter than 1/4000 is past the shutter's end: it takes its shortest, 1/8000, before it gives up
    # (it stopped at 1/4000 and called that the shortest exposure)
    assert sorted(frame.exposure_label for frame in bracket.frames) == ["1/4000", "1/8000"]  # frames: shortest first
    assert any("at 1/8000 s, the shortest exposure: add an ND filter" in note for note in bracket.notes)


def test_darks_are_captured_at_the_light_exposures(tmp_path, capsys):
    out = tmp_path / "capture"
    assert main(["capture", "bracket", "--camera", "sim-usb", "--profile", "simulated", "--out", str(out),
                 "--size", "64x48", "--psf", "dirac", "--stops", "3", "--darks", "--seed", "2"]) == 0
    lights, darks = load_bracket(out), load_bracket(out / "darks")
    assert darks.kind == "dark" and [f.exposure_label for f in darks.frames] == [f.exposure_label for f in lights.frames]
    dark_pixels = read_raw(darks.paths()[-1]).bayer_dn.astype(float)
    assert abs(np.median(dark_pixels) - 512) <= 1
    assert "6 frames" in capsys.readouterr().out


def test_capture_never_overwrites(tmp_path, capsys):
    out = tmp_path / "capture"
    argv = ["capture", "bracket", "--profile", "simulated", "--out", str(out), "--size", "64x48", "--psf", "dirac",
            "--stops", "2"]
    assert main(argv) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    capsys.readouterr()
    assert main(argv) == 1
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and "never overwritten" in error
    assert before == {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}


@pytest.mark.parametrize("size", ["0x0", "1x48", "64"])
def test_impossible_frame_sizes_are_usage_errors(tmp_path, size, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["capture", "bracket", "--out", str(tmp_path / "x"), "--size", size])
    assert exit_info.value.code == 2 and capsys.readouterr().err.count("\n") == 1
    assert not (tmp_path / "x").exists()


def test_usb_without_a_camera_is_one_line_and_exit_1(tmp_path, capsys):
    assert main(["capture", "bracket", "--camera", "usb", "--out", str(tmp_path / "x")]) == 1
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and ("no Sony camera" in error or "no USB backend" in error)
    assert not (tmp_path / "x").exists()


def _write_frame(simulated, folder, name, exposure_s, iso, when):
    simulated.set_exposure(exposure_s, iso=iso)
    return simulated.write_frame(folder / name, simulated.render_dn(), simulated.settings(), when)


def test_ingest_separates_interleaved_brackets_and_reports_a_stray_file(tmp_path, capsys):
    _, simulated = small_camera("sim")
    start = dt.datetime(2026, 5, 1, 21, 0, 0)
    exposures = (1 / 4000, 1 / 500, 1 / 60)
    for k, exposure in enumerate(exposures):  # two brackets shot alternately at ISO 100 and 400
        _write_frame(simulated, tmp_path, f"a{k}.dng", exposure, 100, start + dt.timedelta(seconds=2 * k))
        _write_frame(simulated, tmp_path, f"b{k}.dng", exposure, 400, start + dt.timedelta(seconds=2 * k + 1))
    _write_frame(simulated, tmp_path, "stray.dng", 1 / 125, 800, start + dt.timedelta(seconds=3))
    result = ingest_folder(tmp_path)
    assert [[f.path.name for f in b] for b in result.brackets] == [["a0.dng", "a1.dng", "a2.dng"],
                                                                   ["b0.dng", "b1.dng", "b2.dng"]]
    assert len(result.report) == 1 and "stray.dng" in result.report[0]

    assert main(["ingest", str(tmp_path)]) == 0
    printed = capsys.readouterr().out
    assert "stray.dng" in printed
    manifests = [load_bracket(tmp_path / f"bracket-0{i}.json") for i in (1, 2)]
    assert [[f.iso for f in m.frames] for m in manifests] == [[100.0] * 3, [400.0] * 3]
    assert all(p.is_file() for m in manifests for p in m.paths())
    assert main(["ingest", str(tmp_path)]) == 1  # manifests exist: refused, not overwritten
    assert "exists" in capsys.readouterr().err


def test_ingest_writes_every_manifest_or_none(tmp_path, capsys, monkeypatch):
    """A full disk at the second manifest leaves no first one behind (a rerun found it and refused)."""
    import errno

    from hdrcam.capture.manifest import Bracket

    _, simulated = small_camera("sim")
    start = dt.datetime(2026, 5, 1, 21, 0, 0)
    for k, exposure in enumerate((1 / 4000, 1 / 500, 1 / 60)):
        _write_frame(simulated, tmp_path, f"a{k}.dng", exposure, 100, start + dt.timedelta(seconds=2 * k))
        _write_frame(simulated, tmp_path, f"b{k}.dng", exposure, 400, start + dt.timedelta(seconds=2 * k + 1))
    written = []
    to_json = Bracket.to_json

    def disk_full_at_the_second(self):
        written.append(self)
        if len(written) == 2:
            raise OSError(errno.ENOSPC, "No space left on device")
        return to_json(self)

    monkeypatch.setattr(Bracket, "to_json", disk_full_at_the_second)
    assert main(["ingest", str(tmp_path)]) == 1
    assert "space" in capsys.readouterr().err and not list(tmp_path.glob("*.json"))
    assert not [path for path in tmp_path.iterdir() if path.name.startswith(".")]


def test_ingest_splits_back_to_back_brackets_on_a_repeated_exposure_and_skips_damaged_files(tmp_path):
    _, simulated = small_camera("sim")
    start = dt.datetime(2026, 5, 1, 21, 0, 0)
    for k in range(6):
        _write_frame(simulated, tmp_path, f"f{k}.dng", (1 / 4000, 1 / 500, 1 / 60)[k % 3], 100,
                     start + dt.timedelta(seconds=k))
    (tmp_path / "broken.arw").write_bytes(b"II*\x00 not really a raw file")
    result = ingest_folder(tmp_path)
    assert [len(b) for b in result.brackets] == [3, 3]
    assert len(result.report) == 1 and result.report[0].startswith("skipped") and "broken.arw" in result.report[0]


def test_raw_reader_is_bit_exact_and_reads_metadata(tmp_path):
    _, simulated = small_camera("sim", scene="night")
    when = dt.datetime(2026, 5, 1, 21, 0, 0)
    path = _write_frame(simulated, tmp_path, "f.dng", 1 / 125, 200, when)
    bayer = simulated.render_dn()
    simulated.write_frame(tmp_path / "g.dng", bayer, simulated.settings(), when)
    raw = read_raw(tmp_path / "g.dng")
    assert np.array_equal(raw.bayer_dn, bayer) and raw.bayer_dn.dtype == np.uint16
    meta = read_raw_metadata(path)
    assert (meta.exposure_s, meta.iso, meta.f_number, meta.timestamp) == (0.008, 200.0, 1.8, when)
    assert meta.cfa_pattern == "RGGB" and meta.camera_model == "Sony ILCE-7"
    assert np.allclose(meta.as_shot_neutral.max(), 1.0)


@pytest.mark.parametrize("content", [b"", b"\x00" * 100, b"II*\x00\x08\x00\x00\x00garbage"])
def test_damaged_raw_files_are_input_errors(tmp_path, content):
    path = tmp_path / "bad.dng"
    path.write_bytes(content)
    with pytest.raises(InputError, match="bad.dng"):
        read_raw(path)
    with pytest.raises(InputError, match="no such"):
        read_raw(tmp_path / "missing.arw")


def test_nearest_shutter_handles_the_extremes():
    assert nearest_shutter(1e-9).label == "1/8000" and nearest_shutter(1e4).label == '30"'


@pytest.mark.parametrize("shortest, note", [(1 / 3000, "--shortest 1/3000 s is not a shutter notch: taken as the "
                                                         "nearest, 1/3200 s"), (1 / 4000, None)])
def test_a_shortest_exposure_between_notches_is_said_to_be_moved(tmp_path, shortest, note):
    """1/3000 s was quietly shot at the 1/3200 notch; a notch's own label (1/4000) says nothing."""
    bracket = shoot("sim", tmp_path, BracketPlan(shortest_s=shortest, stops=2, ev_step=3.0), scene="flat:0.2")
    moved = [text for text in bracket.notes if "not a shutter notch" in text]
    assert moved == ([note] if note else [])
