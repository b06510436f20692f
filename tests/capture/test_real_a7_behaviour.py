"""The usb client against an A7 that behaves as libgphoto2 documents (hdrcam.capture.emulator's faults), and the
issue's acceptance cases through HDRCAM_USB_BACKEND and ``hdrcam capture bracket --camera usb``."""

from __future__ import annotations

import json
import struct

import numpy as np
import pytest

from hdrcam.capture.camera import CameraError, CameraNotFound
from hdrcam.capture.emulator import BULK_PACKET_BYTES, Faults, Latencies
from hdrcam.capture.ptp.codes import DataType, Property
from hdrcam.capture.ptp.datasets import Reader, Writer
from hdrcam.capture.ptp.transport import Stalled
from hdrcam.capture.sony import usb_backend_from_environment
from hdrcam.cli import main
from hdrcam.io.raw import read_raw
from tests.capture import hooked_a7
from tests.capture.helpers import emulated_a7 as emulated

AF_S = 2



# -- the client, fault by fault ------------------------------------------------------------------------------------
def test_af_s_shots_wait_for_focus_found_and_mf_shots_do_not(tmp_path):
    for focus_mode, latency_s in ((AF_S, 1.5), (1, 1.5)):
        camera, body = emulated(Latencies(focus_s=latency_s), focus_mode=focus_mode)
        with camera:
            started = body.clock.monotonic()
            camera.capture(tmp_path, f"f{focus_mode}")
            waited = body.clock.monotonic() - started
        assert body.shots == [{"focused": True, "exposure_s": body.camera.true_exposure_s()}]
        assert (waited >= latency_s) == (focus_mode == AF_S)


def test_no_focus_is_a_clear_error_and_no_shot(tmp_path):
    camera, body = emulated(focus_mode=AF_S, never_focus=True)
    with camera, pytest.raises(CameraError, match="no focus within 5 s.*MF"):
        camera.capture(tmp_path, "f")
    assert body.shots == [] and not list(tmp_path.iterdir())


def test_stale_and_early_object_added_events_never_make_the_client_ask_early(tmp_path):
    camera, body = emulated(Latencies(image_ready_s=2.0), stale_object_added=True, early_object_added=True)
    with camera:
        for k in range(3):
            camera.capture(tmp_path, f"f{k}")
    assert body.premature_requests == 0 and body.downloads == 3


@pytest.mark.parametrize("stalls, recovers", [(1, True), (2, True), (3, False)])
def test_a_stalled_download_is_cleared_and_retried_a_bounded_number_of_times(tmp_path, stalls, recovers):
    camera, body = emulated(stalls_during_download=stalls)
    with camera:
        if recovers:
            frame = camera.capture(tmp_path, "f")
            assert frame.raw.bayer_dn.shape == (48, 64)
            assert sum("cleared the halt" in line for line in camera.session.log) == stalls
        else:
            with pytest.raises(Stalled, match="stalled"):
                camera.capture(tmp_path, "f")
            assert not list(tmp_path.iterdir())


def test_raw_plus_jpeg_keeps_the_raw_and_drops_the_jpeg(tmp_path):
    camera, body = emulated(image_quality=0x13)
    with camera:
        frames = [camera.capture(tmp_path, f"f{k}") for k in range(2)]
        assert sum("dropped DSC" in line and ".JPG" in line for line in camera.session.log) == 2
    assert [frame.path.suffix for frame in frames] == [".dng", ".dng"] and body.downloads == 4
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f0.dng", "f1.dng"] and body.premature_requests == 0


def test_images_of_whole_packets_end_with_a_zlp_and_download_intact(tmp_path):
    camera, body = emulated(whole_packet_images=True)
    with camera:
        frame = camera.capture(tmp_path, "f")
    assert (frame.path.stat().st_size + 12) % BULK_PACKET_BYTES == 0 and read_raw(frame.path).bayer_dn.size


def test_properties_of_every_ptp_type_are_parsed():
    camera, _ = emulated(odd_property_types=True)
    with camera:
        properties = camera.properties
    assert properties[0xD2A0].current == (1, 2, 3) and properties[0xD2A1].current == -(1 << 100)
    assert properties[0xD2A2].current == (1 << 128) - 1 and properties[0xD2A3].current == "FE 50mm F1.8"
    assert properties[0xD2A4].form == ((), (-1, 0, 1))


def test_128_bit_and_array_values_are_byte_exact():
    assert Writer().value(DataType.INT128, -2).bytes() == struct.pack("<qq", -2, -1)
    assert Writer().value(DataType.ARRAY | DataType.UINT16, (7, 8)).bytes() == struct.pack("<IHH", 2, 7, 8)
    assert Reader(struct.pack("<QQ", 5, 1)).value(DataType.UINT128) == 5 + (1 << 64)


def test_an_empty_sdio_answer_is_asked_again_then_the_handshake_goes_on_as_libgphoto2s_does():
    camera, _ = emulated(empty_sdio_answers=2)
    with camera:
        assert camera.protocol_version == 0xC8
        assert sum("answered empty" in line for line in camera.session.log) == 2
    camera, _ = emulated(empty_sdio_answers=100)
    with camera:
        assert camera.protocol_version == 0 and any("stayed empty" in line for line in camera.session.log)
        assert camera.settings().exposure_label == "1/60"


@pytest.mark.parametrize("faults, message", [({"exposure_mode": 2}, "mode dial.*M"),
                                             ({"image_quality": 0x03}, "JPEG only.*RAW"),
                                             ({"iso_auto": True}, "ISO is on Auto"),
                                             ({"drive_mode": 0x8337}, "drive mode is continuous bracket 0.3 EV.*Single Shooting"),
                                             ({"drive_mode": 0x00010002}, "drive mode is continuous")])
def test_a_body_set_up_wrongly_is_refused_before_any_shot(faults, message):
    camera, body = emulated(**faults)
    with pytest.raises(CameraError, match=message):
        with camera:
            camera.set_exposure(exposure_s=1 / 250, iso=100)
    assert body.shots == []


def test_focus_drive_and_firmware_are_reported():
    camera, _ = emulated(focus_mode=AF_S)
    with camera:
        assert camera.details() == {"focus_mode": "AF-S", "drive_mode": "single", "firmware": "3.20"}
        assert not camera.focus_is_manual and Property.FOCUS_MODE in camera.properties


@pytest.mark.parametrize("spec, message", [("nomodule", "module:callable"), ("no.such.module:f", "cannot load"),
                                           ("tests.capture.hooked_a7:LATENCIES", "not a callable"),
                                           ("tests.capture.hooked_a7:Latencies", "not a usb.backend")])
def test_a_bad_usb_backend_hook_is_one_clear_error(monkeypatch, spec, message):
    monkeypatch.setenv("HDRCAM_USB_BACKEND", spec)
    with pytest.raises(CameraNotFound, match=message):
        usb_backend_from_environment()


# -- acceptance, through the hook and the command line ---------------------------------------------------------
def _capture(monkeypatch, tmp_path, faults: Faults, *extra):
    monkeypatch.setenv("HDRCAM_USB_BACKEND", "tests.capture.hooked_a7:backend")
    monkeypatch.setattr(hooked_a7, "FAULTS", faults)
    hooked_a7.CAMERAS.clear()
    out = tmp_path / "b"
    status = main(["capture", "bracket", "--camera", "usb", "--profile", "simulated", "--out", str(out),
                   "--stops", "3", "--ev-step", "1", "--shortest", "1/1000", "--iso", "400", *extra])
    return status, out, hooked_a7.CAMERAS[-1]


def test_acceptance_a_bracket_survives_everything_a_real_a7_does(monkeypatch, tmp_path):
    faults = Faults(focus_mode=AF_S, stale_object_added=True, early_object_added=True, whole_packet_images=True,
                    odd_property_types=True, empty_sdio_answers=1, stalls_during_download=1)
    with pytest.warns(UserWarning, match="focus mode is AF-S"):
        status, out, body = _capture(monkeypatch, tmp_path, faults)
    assert status == 0
    manifest = json.loads((out / "bracket.json").read_text())
    assert manifest["status"] == "complete"
    assert [f["exposure_label"] for f in manifest["frames"]] == ["1/1000", "1/500", "1/250"]
    assert manifest["camera"]["focus_mode"] == "AF-S" and manifest["camera"]["firmware"] == "3.20"
    assert len(body.shots) == 3 and all(shot["focused"] for shot in body.shots) and body.premature_requests == 0
    signal = [float(read_raw(out / f["file"]).bayer_dn.astype(float).mean() - 512) for f in manifest["frames"]]
    true_s = [shot["exposure_s"] for shot in body.shots]
    assert true_s == sorted(true_s) and np.allclose(np.diff(np.log2(true_s)), 1.0, atol=0.1)
    assert np.allclose(np.array(signal) / np.array(true_s), signal[0] / true_s[0], rtol=0.03)


def test_acceptance_a_disconnect_mid_bracket_keeps_the_frames_taken(monkeypatch, tmp_path, capsys):
    status, out, body = _capture(monkeypatch, tmp_path, Faults(disconnect_after_downloads=1))
    err = capsys.readouterr().err
    errors = [line for line in err.splitlines() if "error" in line]  # (the progress bar also writes to stderr)
    assert status == 1 and len(errors) == 1 and "disconnected" in errors[0]
    manifest = json.loads((out / "bracket.json").read_text())
    assert manifest["status"] == "incomplete" and [f["exposure_label"] for f in manifest["frames"]] == ["1/1000"]
    assert (out / manifest["frames"][0]["file"]).is_file()


@pytest.mark.parametrize("faults, message", [(Faults(exposure_mode=3), "M"), (Faults(iso_auto=True), "Auto"),
                                             (Faults(image_quality=0x02), "JPEG only")])
def test_acceptance_a_body_set_up_wrongly_exits_1_before_any_shot(monkeypatch, tmp_path, capsys, faults, message):
    status, out, body = _capture(monkeypatch, tmp_path, faults)
    err = capsys.readouterr().err
    errors = [line for line in err.splitlines() if "error" in line]
    assert status == 1 and len(errors) == 1 and message in errors[0] and "internal error" not in err
    assert body.shots == [] and not list(out.glob("frame-*"))


# -- a session that stops half-way, and bodies that differ --------------------------------------------------------
def test_a_failure_while_the_shutter_is_held_releases_both_buttons(tmp_path):
    camera, body = emulated()
    with camera:
        transact = camera.session.transact
        release = struct.pack("<H", 1)

        def interrupted_at_the_full_release(operation, *params, data_out=None, **options):
            if params == (Property.SONY_FULL_PRESS,) and data_out == release:
                camera.session.transact = transact  # once
                raise KeyboardInterrupt  # Ctrl-C before the release reaches the body
            return transact(operation, *params, data_out=data_out, **options)

        camera.session.transact = interrupted_at_the_full_release
        with pytest.raises(KeyboardInterrupt):
            camera.capture(tmp_path, "f")
        assert camera.session.transact is transact  # the fault fired
    assert body._buttons == {Property.SONY_HALF_PRESS: 1, Property.SONY_FULL_PRESS: 1}  # 1 released, 2 held


def test_ctrl_c_during_a_download_leaves_the_camera_ready_for_the_next_run(tmp_path):
    camera, body = emulated()
    backend = camera._device.backend
    reads, original = [], backend.bulk_read

    def bulk_read(*arguments):
        if body._downloading:
            reads.append(1)
            if len(reads) == 2:
                raise KeyboardInterrupt  # the image is half-way through the pipe
        return original(*arguments)

    backend.bulk_read = bulk_read
    with pytest.raises(KeyboardInterrupt), camera:
        camera.capture(tmp_path, "first")
    assert not body.in_pipe.transfers  # the transaction was cancelled: nothing left for the next session
    from hdrcam.capture.sony import SonyA7Camera, find_sony_camera

    with SonyA7Camera(find_sony_camera(backend), clock=body.clock, cover_lens=lambda covered: None) as again:
        assert read_raw(again.capture(tmp_path, "second").path).bayer_dn.shape == (48, 64)


def test_data_left_on_the_pipe_by_a_killed_run_is_reset_away_at_open_session(tmp_path):
    camera, body = emulated()
    body.in_pipe.queue(bytes(range(256)) * 40)  # the middle of an image another process stopped reading
    with camera:
        assert any("reset the device" in line for line in camera.session.log)
        assert camera.session.log.count("OpenSession after the reset: opened") == 1
        assert camera.capture(tmp_path, "f").raw.bayer_dn.shape == (48, 64)


def test_a_pipe_left_stalled_is_reset_away_at_open_session(tmp_path):
    """library.c camera_init resets the device and tries OpenSession again after an I/O error; a bulk-in halt left
    by a killed run failed the handshake with Stalled."""
    camera, body = emulated()
    body.halted = True
    with camera:
        assert camera.session.log.count("OpenSession after the reset: opened") == 1
        assert camera.capture(tmp_path, "f").raw.bayer_dn.shape == (48, 64)


def test_a_sony_body_reporting_the_mtp_extension_is_taken_as_sony_and_others_are_told_to_use_pc_remote():
    camera, _ = emulated(vendor_extension_id=0xFFFFFFFF)  # libgphoto2: MTP + "Sony Corporation" = Sony (PTP/IP)
    with camera:
        assert camera.model == "Sony Corporation ILCE-7"
    camera, _ = emulated(vendor_extension_id=6)  # a body in MTP mode (Microsoft's extension)
    with pytest.raises(CameraError, match="does not offer Sony's PTP extensions.*PC Remote"):
        with camera:
            pass


def test_a_lens_without_contacts_records_no_aperture_in_strict_json(monkeypatch, tmp_path):
    status, out, body = _capture(monkeypatch, tmp_path, Faults(lens_reports_aperture=False))
    assert status == 0

    def refuse(constant):
        raise ValueError(f"not JSON: {constant}")

    manifest = json.loads((out / "bracket.json").read_text(), parse_constant=refuse)
    assert [frame["f_number"] for frame in manifest["frames"]] == [None] * 3


def test_a_garbled_download_is_set_aside_and_shot_again_on_resume(monkeypatch, tmp_path, capsys):
    status, out, body = _capture(monkeypatch, tmp_path, Faults(damaged_image=2))
    assert status == 1 and "internal error" not in capsys.readouterr().err
    manifest = json.loads((out / "bracket.json").read_text())
    assert manifest["status"] == "incomplete" and [f["file"] for f in manifest["frames"]] == ["frame-00.dng"]
    assert (out / "unreadable-frame-01.dng").is_file() and not (out / "frame-01.dng").exists()
    assert any("does not read as RAW" in note and "unreadable-frame-01.dng" in note for note in manifest["notes"])
    status, out, body = _capture(monkeypatch, tmp_path, Faults(), "--resume")
    manifest = json.loads((out / "bracket.json").read_text())
    assert status == 0 and manifest["status"] == "complete" and len(manifest["frames"]) == 3
    for frame in manifest["frames"]:
        assert read_raw(out / frame["file"]).bayer_dn.shape == (48, 64)
