"""What ``capture bracket`` accepts: frame sizes LibRaw opens, the camera's ISO settings, EV steps as fractions or
the camera's labels, plans that fit the shutter (refused up front, with advice that works); the frame count of a
resumed capture."""

from __future__ import annotations

import datetime as dt
import errno
import re
from fractions import Fraction

import numpy as np
import pytest

import hdrcam
from hdrcam.capture.backends import SIMULATED_MIN_SIDE_PX as MIN_PX
from hdrcam.capture.bracket import BracketPlan
from hdrcam.capture.camera import ExposureSettings
from hdrcam.capture.manifest import load_bracket
from hdrcam.capture.notches import bracket_notches
from hdrcam.cli import build_parser, main
from hdrcam.errors import InputError
from hdrcam.io.raw import read_raw
from tests.capture.helpers import small_camera

SMALL = dict(camera="sim", profile="simulated", scene="flat:0.2", psf="dirac", size_px=(64, 48), ev_step=3.0)


def parse(*options: str):
    return build_parser("capture").parse_args(["capture", "bracket", "--out", "x", *options])


def capture_help(capsys) -> str:
    """``capture bracket --help``, with its lines joined."""
    with pytest.raises(SystemExit):
        parse("--help")
    return " ".join(capsys.readouterr().out.split())


def refused_usage(capsys, *options: str) -> str:
    """The one-line usage error (exit 2) of ``capture bracket OPTIONS``."""
    with pytest.raises(SystemExit) as stopped:
        parse(*options)
    assert stopped.value.code == 2
    return capsys.readouterr().err


# -- frame size ---------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("width, height, opens", [(MIN_PX, MIN_PX, True), (MIN_PX + 1, MIN_PX, True),
                                                   (MIN_PX - 1, MIN_PX, False), (MIN_PX, MIN_PX - 1, False)])
def test_libraw_opens_a_simulated_dng_from_the_smallest_size_on(tmp_path, width, height, opens):
    simulated = small_camera()[1]
    path = tmp_path / "frame.dng"
    path.write_bytes(simulated.frame_bytes(np.full((height, width), 600, np.uint16),
                                           ExposureSettings(0.01, "1/100", 100.0, 2.8), dt.datetime(2024, 1, 1)))
    if opens:
        assert read_raw(path).bayer_dn.shape == (height, width)
    else:
        with pytest.raises(Exception, match="LibRaw does not open it"):
            read_raw(path)


@pytest.mark.parametrize("size", ["21x22", "22x21", "2x2"])
def test_a_size_libraw_cannot_open_is_refused_before_anything_is_written(tmp_path, capsys, size):
    assert "integers >= 22" in refused_usage(capsys, "--size", size)
    width, height = map(int, size.split("x"))
    with pytest.raises(InputError, match=f"use --size {max(width, 22)}x{max(height, 22)} or larger"):
        hdrcam.capture_bracket(tmp_path / "b", **dict(SMALL, size_px=(width, height)))
    assert not (tmp_path / "b").exists()
    assert "at least 22x22" in capture_help(capsys)


def test_the_smallest_size_captures_frames_libraw_reads(tmp_path):
    bracket, _ = hdrcam.capture_bracket(tmp_path / "b", **dict(SMALL, size_px=(22, 22), stops=2))
    assert [read_raw(path).bayer_dn.shape for path in bracket.paths()] == [(22, 22)] * 2


# -- ISO ----------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("iso, nearest", [(25, "100"), (64, "100"), (80, "100"), (137, "125 and 160"),
                                          (51200, "25600")])
def test_an_iso_the_camera_does_not_offer_is_refused_up_front_naming_the_nearest(tmp_path, capsys, iso, nearest):
    error = refused_usage(capsys, "--iso", str(iso))
    assert f"no ISO {iso} (nearest: {nearest})" in error and "100, 125, 160" in error and "25600" in error
    with pytest.raises(InputError, match=f"nearest: {nearest}"):
        BracketPlan(shortest_s=1 / 4000, stops=2, ev_step=3.0, iso=iso)
    with pytest.raises(InputError, match="offers no ISO"):
        hdrcam.capture_bracket(tmp_path / "b", **dict(SMALL, stops=2, iso=iso))
    assert not (tmp_path / "b").exists()


@pytest.mark.parametrize("kind", ["sim", "sim-usb"])
def test_cameras_land_on_the_iso_asked_or_refuse_it(kind):
    camera, _ = small_camera(kind)
    with camera:
        assert camera.set_exposure(iso=125).iso == 125
        for iso in (80, 137, 51200):
            with pytest.raises(InputError, match="offers no ISO"):
                camera.set_exposure(iso=iso)
        assert camera.settings().iso == 125


@pytest.mark.parametrize("kind", ["sim", "sim-usb"])
def test_the_manifest_s_iso_is_the_frames_iso(tmp_path, kind):
    hdrcam.capture_bracket(tmp_path / "b", **dict(SMALL, camera=kind, stops=2, iso=1250))
    manifest = load_bracket(tmp_path / "b")
    assert manifest.options["plan"]["iso"] == 1250 and [frame.iso for frame in manifest.frames] == [1250, 1250]


# -- EV step ------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("text, thirds", [("1/3", 1), ("0.3", 1), ("0.33", 1), ("0.333", 1), (".3", 1),
                                          ("0.3333333333333333", 1), ("2/3", 2), ("0.7", 2), ("0.67", 2),
                                          ("0.667", 2), ("1", 3), ("1.0", 3), ("4/3", 4), ("1.3", 4), ("1.33", 4),
                                          ("1.7", 5), ("1.67", 5), ("2", 6), ("2.3", 7), ("2.33", 7), ("2.7", 8),
                                          ("2.67", 8), ("3", 9), ("6/2", 9), ("0.666", 2), ("0.6666", 2),
                                          ("1.6666", 5)])  # 2/3 cut short at 3 or more digits (bc prints .6666)
def test_ev_steps_are_read_as_fractions_or_the_camera_s_rounded_labels(text, thirds):
    assert parse("--ev-step", text).ev_step == thirds / 3  # exactly the float of k/3, however it was written


@pytest.mark.parametrize("text", ["0.5", "1/2", "1.5", "0.35", "0.30", "0.66", "0.6", "0.4", "0", "0/3", "1/0", "-1",
                                  "1e0", "nan", "inf", "one"])
def test_ev_steps_that_are_no_whole_number_of_notches_are_refused(capsys, text):
    error = refused_usage(capsys, "--ev-step", text)
    assert "--ev-step" in error and ("1/3 EV notches" in error or "such as 1, 2/3 or 0.7" in error)


def test_the_help_says_which_ev_steps_are_read(capsys):
    text = capture_help(capsys)
    assert "0.3, 0.7, 1, 1.3, 1.7" in text and "1/3, 2/3" in text


# -- plans beyond the shutter ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("shortest_s, stops, ev_step, advice", [
    (1 / 4000, 9, 3.0, "choose fewer stops (--stops 6 or fewer) or a smaller EV step (--ev-step 2 or less)"),
    (1 / 60, 5, 3.0, "choose a shorter shortest exposure (--shortest 1/125 or shorter), fewer stops (--stops 4 or "
                     "fewer) or a smaller EV step (--ev-step 8/3 or less)"),
    (1 / 4000, 65, 1 / 3, "choose fewer stops (--stops 52 or fewer)"),
    (30.0, 2, 1 / 3, "choose a shorter shortest exposure (--shortest 25 or shorter) or fewer stops (--stops 1 or "
                     "fewer)")])
def test_a_bracket_beyond_30_s_is_refused_with_plans_that_fit(shortest_s, stops, ev_step, advice):
    with pytest.raises(InputError) as refused:
        bracket_notches(shortest_s, stops, ev_step)
    message = str(refused.value)
    assert message.endswith(advice) and "longer than the shutter's 30 s" in message
    assert f"{stops} exposures {Fraction(ev_step).limit_denominator(3)} EV apart" in message  # 1/3, not 0.333...
    suggested = dict(re.findall(r"\((--[a-z-]+) (\S+) or", message))
    plans = {"--shortest": lambda value, beyond: (float(Fraction(value)) * 2 ** (beyond / 3), stops, ev_step),
             "--stops": lambda value, beyond: (shortest_s, int(value) + beyond, ev_step),
             "--ev-step": lambda value, beyond: (shortest_s, stops, float(Fraction(value)) + beyond / 3)}
    for option, value in suggested.items():  # each limit suggested fits, and is the limit: a notch more does not
        assert len(bracket_notches(*plans[option](value, 0))) == plans[option](value, 0)[1]
        with pytest.raises(InputError):
            bracket_notches(*plans[option](value, 1))


def test_a_bracket_beyond_30_s_is_refused_before_the_folder_is_claimed(tmp_path, capsys):
    out = tmp_path / "b"
    status = main(["capture", "bracket", "--camera", "sim", "--profile", "simulated", "--psf", "dirac", "--size",
                   "64x48", "--stops", "9", "--ev-step", "3", "--out", str(out)])
    assert status == 1 and "--ev-step 2 or less" in capsys.readouterr().err and not out.exists()


@pytest.mark.parametrize("option, value", [("--hot-pixels", "nan"), ("--hot-pixels", "1"), ("--hot-pixels", "-1e-5"),
                                           ("--exposure-error", "1e400"), ("--exposure-error", "-0.1")])
def test_defect_fractions_out_of_range_are_usage_errors_naming_the_option(tmp_path, capsys, option, value):
    """They were exit 1 naming the API's fields (hot_pixel_fraction nan: ...) after the parse."""
    out = tmp_path / "b"
    with pytest.raises(SystemExit) as stopped:
        main(["capture", "bracket", "--size", "64x48", "--out", str(out), f"{option}={value}"])
    assert stopped.value.code == 2 and capsys.readouterr().err == (
        f"hdrcam capture bracket: error: argument {option}: expected a fraction from 0 up to (not including) 1, "
        f"got {value!r} (see 'hdrcam capture bracket --help')\n")
    assert not out.exists()
    assert parse(option, "0").__dict__[option[2:].replace("-", "_")] == 0.0


# -- resume -------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("failing_shot, shot_on_resume", [(2, 5), (5, 2)])  # 3 lights, then 3 darks
def test_a_resumed_capture_counts_the_frames_it_shot(tmp_path, monkeypatch, failing_shot, shot_on_resume):
    from hdrcam.capture.simulated import SimulatedCamera

    capture, calls = SimulatedCamera.capture, []

    def disk_full_once(self, folder, stem, *, dark=False):
        calls.append(stem)
        if len(calls) == failing_shot:
            raise OSError(errno.ENOSPC, "No space left on device")
        return capture(self, folder, stem, dark=dark)

    options = dict(SMALL, stops=3, darks=True)
    with monkeypatch.context() as patch:
        patch.setattr(SimulatedCamera, "capture", disk_full_once)
        with pytest.raises(OSError):
            hdrcam.capture_bracket(tmp_path / "b", **options)
    lines = []
    bracket, darks = hdrcam.capture_bracket(tmp_path / "b", resume=True, log=lines.append, **options)
    assert bracket.status == darks.status == "complete" and len(bracket.frames) == len(darks.frames) == 3
    assert any(line.startswith(f"{shot_on_resume} frames in ") for line in lines), lines


CAPTURE = ["capture", "bracket", "--profile", "simulated", "--psf", "dirac", "--size", "64x48", "--stops", "3",
           "--ev-step", "3", "--seed", "1"]


def capture(capsys, out, *options: str) -> tuple[int, list[str]]:
    """``hdrcam capture bracket`` into ``out``: (exit status, the error lines on stderr)."""
    capsys.readouterr()
    status = main([*CAPTURE, "--out", str(out), *options])
    return status, [line for line in capsys.readouterr().err.splitlines() if "error:" in line]


def files_under(folder) -> dict[str, bytes]:
    return {str(path.relative_to(folder)): path.read_bytes() for path in sorted(folder.rglob("*")) if path.is_file()}


OPTIONS_DIFFER = "; resume with the same options, or choose another --out"


@pytest.mark.parametrize("options, differs", [
    (["--camera", "sim", "--iso", "200"], 'plan {"iso": 100.0}, this run asks for {"iso": 200.0}' + OPTIONS_DIFFER),
    (["--camera", "sim", "--ev-step", "2"], 'plan {"ev_step": 3.0}, this run asks for {"ev_step": 2.0}'
                                            + OPTIONS_DIFFER),
    (["--camera", "sim", "--scene", "flat:0.2"], 'scene "point source, power 50, at (32.012, 24.450) px", this run '
                                                 'asks for "flat field 0.2"' + OPTIONS_DIFFER),
    (["--camera", "sim-usb"], "camera {'backend': 'sim', 'model': 'Sony ILCE-7 (simulated, simulated)'}, this run "
                              "has {'backend': 'sim-usb', 'model': 'Sony Corporation ILCE-7', 'focus_mode': 'MF', "
                              "'drive_mode': 'single', 'firmware': '3.20'}; resume with the same camera, profile "
                              "and options, or choose another --out")])
def test_darks_added_to_a_complete_capture_are_refused_when_the_plan_or_camera_differ(tmp_path, capsys, options,
                                                                                       differs):
    """`--resume --darks` on complete lights without darks checks the lights as any --resume does, before a dark
    is shot (it shot darks at ISO 200 for lights at ISO 100, or on another backend)."""
    out = tmp_path / "b"
    assert capture(capsys, out, "--camera", "sim") == (0, [])
    before = files_under(out)
    assert capture(capsys, out, *options, "--resume", "--darks") == (
        1, [f"hdrcam capture bracket: error: --resume: {out}/bracket.json was shot with {differs}"])
    assert files_under(out) == before and not (out / "darks").exists()
    assert capture(capsys, out, "--camera", "sim", "--resume", "--darks") == (0, [])  # the same request: darks
    assert load_bracket(out / "darks").status == "complete" and load_bracket(out).options.get("darks") is None


def stop_at_shot(monkeypatch, shot: int):
    """The simulated camera's ``shot``-th capture (1: the first) fails with a full disk."""
    from hdrcam.capture.simulated import SimulatedCamera

    capture_, calls = SimulatedCamera.capture, []

    def disk_full(self, folder, stem, *, dark=False):
        calls.append(stem)
        if len(calls) == shot:
            raise OSError(errno.ENOSPC, "No space left on device")
        return capture_(self, folder, stem, dark=dark)

    monkeypatch.setattr(SimulatedCamera, "capture", disk_full)


@pytest.mark.parametrize("stopped_at, refusal", [
    (2, "was started with --darks; resume with --darks too, or choose another --out"),  # in the lights
    (5, "was started with --darks and its darks are not complete; resume with --darks too")])  # in the darks
def test_a_capture_started_with_darks_is_not_resumed_without_them(tmp_path, capsys, monkeypatch, stopped_at,
                                                                  refusal):
    out = tmp_path / "b"
    with monkeypatch.context() as patch:
        stop_at_shot(patch, stopped_at)
        assert capture(capsys, out, "--darks")[0] == 1
    before = files_under(out)
    assert capture(capsys, out, "--resume") == (
        1, [f"hdrcam capture bracket: error: --resume: {out}/bracket.json {refusal}"])
    assert files_under(out) == before
    assert capture(capsys, out, "--resume", "--darks") == (0, [])
    assert load_bracket(out).status == load_bracket(out / "darks").status == "complete"
    assert load_bracket(out).options["darks"] is True


def test_darks_may_be_added_when_resuming_a_capture_started_without_them(tmp_path, capsys, monkeypatch):
    out = tmp_path / "b"
    with monkeypatch.context() as patch:
        stop_at_shot(patch, 2)
        assert capture(capsys, out)[0] == 1
    assert "darks" not in load_bracket(out).options
    assert capture(capsys, out, "--resume", "--darks") == (0, [])
    lights, darks = load_bracket(out), load_bracket(out / "darks")
    assert lights.status == darks.status == "complete" and len(darks.frames) == 3
    assert lights.options["darks"] is True
    assert capture(capsys, out, "--resume") == (1, [f"hdrcam capture bracket: error: {out}: the capture is "
                                                    "complete; nothing to resume"])


@pytest.mark.parametrize("option, message", [
    ("--roi=0,0,0,5", "--roi 0,0,0,5: expected X,Y,WIDTH,HEIGHT"),
    ("--roi=60,40,100,100", "--roi 60,40,100,100 reaches past the 64 x 48 px frame"),
    ("--shortest=1/10000", "1/10000 s is beyond the shutter's range, 1/8000 to 30 s"),
    ("--shortest=40", "40 s is beyond the shutter's range")])
def test_a_region_or_shortest_exposure_the_camera_cannot_take_is_refused_before_the_folder_is_claimed(
        tmp_path, capsys, option, message):
    out = tmp_path / "b"
    status = main(["capture", "bracket", "--size", "64x48", "--psf", "dirac", "--scene", "flat:0.5", "--auto",
                   "--stops", "1", option, "--out", str(out)])
    assert status == 1 and message in capsys.readouterr().err and not out.exists()


@pytest.mark.parametrize("shortest_s, label", [(1 / 8000, "1/8000"), (30.0, '30"'), (1 / 9000, "1/8000"),
                                               (34.0, '30"')])
def test_the_shutter_s_ends_are_taken_to_within_half_a_notch(shortest_s, label):
    assert bracket_notches(shortest_s, 1, 1.0)[0].label == label
    BracketPlan(shortest_s=shortest_s, stops=1, ev_step=1.0)


def test_manifests_with_fields_of_the_wrong_type_are_one_line_errors_and_old_nan_apertures_load(tmp_path):
    with small_camera("sim")[0] as camera:
        hdrcam.capture.bracket.BracketCapture(camera, hdrcam.profiles.load_profile("simulated").camera, tmp_path,
                                              backend="sim", profile="simulated", show_progress=False).shoot(
            BracketPlan(shortest_s=1 / 1000, stops=1, ev_step=1.0))
    manifest = (tmp_path / "bracket.json").read_text()
    for field, bad in (('"exposure_s": 0.001', '"exposure_s": "abc"'), ('"exposure_s": 0.001', '"exposure_s": 0'),
                       ('"kind": "light"', '"kind": 3'), ('"iso": 100.0', '"iso": -1')):
        assert field in manifest
        (tmp_path / "bracket.json").write_text(manifest.replace(field, bad))
        with pytest.raises(InputError, match="malformed bracket manifest"):
            load_bracket(tmp_path)
    (tmp_path / "bracket.json").write_text(re.sub(r'"f_number": [0-9.]+', '"f_number": NaN', manifest))
    assert load_bracket(tmp_path).frames[0].f_number != load_bracket(tmp_path).frames[0].f_number  # NaN kept


def test_dark_frames_without_a_terminal_are_a_one_line_camera_error(monkeypatch):
    from hdrcam.capture.camera import CameraError
    from hdrcam.capture.sony import TerminalLensCover

    def no_terminal(prompt):
        raise EOFError

    monkeypatch.setattr("builtins.input", no_terminal)
    with pytest.raises(CameraError, match="standard input, which has ended"):
        TerminalLensCover()(True)


@pytest.mark.parametrize("code, advice", [(errno.EACCES, "udev rule"), (errno.EBUSY, "another program holds"),
                                          (errno.EIO, "cable, power and PC-remote mode")])
def test_usb_errors_get_advice_for_what_went_wrong(code, advice):
    import usb.core

    from hdrcam.errors import failure_message

    assert advice in failure_message(usb.core.USBError("it failed", errno=code))


@pytest.mark.parametrize("seconds, label", [(0.0015625, "1/640"), (1 / 8000, "1/8000"), (2.5, '2.5"'), (1 / 3, "1/3"),
                                            (0.4, '0.4"'), (0.3, '0.3"'), (0.0013, "1/769")])
def test_exposures_are_labelled_as_cameras_label_them(seconds, label):
    from hdrcam.capture.notches import exposure_label

    assert exposure_label(seconds) == label


@pytest.mark.parametrize("profile, spacing_px", [("simulated", 72.6), ("sony-a7-zeiss50-rank1", 264.6)])
def test_the_default_pinhole_target_leaves_room_for_the_cameras_psf(tmp_path, profile, spacing_px):
    """The simulated pinhole target's default spacing follows the camera's PSF: 72.6 px for the simulated
    profile's 63 px PSF, the same margin beyond the A7 profile's 255 px one (at 72 px calibrate refused the A7's
    target as crowded, and the smaller --size it suggested cut the DOE's streaks into sources of their own); the
    0.6 px beyond a whole pixel spread the pinholes over the CFA's phases."""
    bracket, _ = hdrcam.capture_bracket(tmp_path / "b", camera="sim", profile=profile, scene="pinholes",
                                        size_px=(600, 400), stops=1)
    assert f"{spacing_px:g} px apart" in bracket.options["scene"], bracket.options["scene"]


def test_the_default_pinhole_grid_puts_pinholes_at_every_cfa_phase():
    """A rigid grid at a whole-pixel pitch with each pinhole moved within its own pixel kept every pinhole in one
    quarter of the 2 x 2 CFA period: blue's PSF core, on the other sites, went unsampled (12.9 % off in L1 on the
    A7 profile's default target). The default pitch spreads them over the whole period, in both axes."""
    from hdrcam.capture.scene import load_scene, pinhole_spacing_for

    for psf_px in (63, 255):
        scene = load_scene("pinholes", 2000, 3000, pinhole_spacing_px=pinhole_spacing_for(psf_px))
        phases = {(int(point.y_px) % 2, int(point.x_px) % 2) for point in scene.points}
        assert phases == {(0, 0), (0, 1), (1, 0), (1, 1)}, (psf_px, phases)
        pitches = np.diff(sorted({round(point.x_px, 6) for point in scene.points}))
        np.testing.assert_allclose(pitches, pinhole_spacing_for(psf_px))  # one rigid pitch


def test_a_pinhole_spacing_below_two_cfa_periods_is_refused_in_one_line():
    """A fractional SPACING once allowed reached the grid as given: pinholes::0.02 made 10 million sources on a
    64 x 64 frame (17 s) and pinholes::0.05 ran capture out of time or memory."""
    from hdrcam.capture.scene import load_scene

    for spec in ("pinholes::0.02", "pinholes:50:3.9", "pinholes::0"):
        with pytest.raises(InputError, match=r"px apart; give a SPACING of at least 4 px"):
            load_scene(spec, 64, 64)
    assert len(load_scene("pinholes::4", 64, 64).points) == 256


@pytest.mark.parametrize("spec, what", [("pinholes:1:-5", "SPACING"), ("pinholes:1:nan", "SPACING"),
                                        ("pinholes:-1:80", "POWER"), ("point:inf", "POWER"), ("flat:-0.5", "LEVEL")])
def test_a_bad_scene_number_is_named_by_its_place_in_the_spec(spec, what):
    """A bad SPACING was reported as 'the level must be finite and >= 0' (of a valid POWER)."""
    from hdrcam.capture.scene import load_scene

    with pytest.raises(InputError) as refused:
        load_scene(spec, 64, 64)
    assert str(refused.value) == f"scene {spec!r}: the {what} must be finite and >= 0"
