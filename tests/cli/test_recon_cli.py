"""design / finetune / evaluate / simulate / reconstruct / demo from the command line, and their bad input."""

from __future__ import annotations

import csv
import json
import subprocess
import sys

import cv2
import numpy as np
import OpenEXR
import pytest

from hdrcam.cli import main
from hdrcam.evaluate.metrics import psnr_linear
from hdrcam.io.exr import read_exr, write_exr
from hdrcam.train.checkpoint import SHIPPED_CHECKPOINT, load_model

TINY = ["--steps", "2", "--crop", "32", "--batch", "1"]


def _one_line_error(capsys, text: str) -> None:
    error = capsys.readouterr().err.strip()
    assert error.count("\n") == 0 and text in error, error


def test_shipped_checkpoint_loads():
    model = load_model()
    assert model.preset == "fast" and model.profile == "simulated" and model.step >= 1000
    assert model.psf.shape == (3, 63, 63) and np.allclose(model.psf.sum(axis=(1, 2)), 1.0, atol=1e-5)
    assert SHIPPED_CHECKPOINT.stat().st_size < 5e6


def test_design_evaluate_and_finetune(tmp_path, capsys):
    run = tmp_path / "run"
    assert main(["design", *TINY, "--psf", "star8", "--out", str(run)]) == 0
    capsys.readouterr()
    assert main(["design", *TINY, "--psf", "star8", "--out", str(run)]) == 1
    _one_line_error(capsys, "already holds a run")
    evaluation = tmp_path / "eval"
    assert main(["evaluate", "--checkpoint", f"mine={run / 'model.pt'}", "--size", "32", "--count", "2",
                 "--out", str(evaluation)]) == 0
    rows = list(csv.DictReader((evaluation / "metrics.csv").open()))
    assert [row["method"] for row in rows] == ["ldr", "hdrcnn-blend", "mine", "mine-network"] * 2
    assert all(np.isfinite(float(row[k])) for row in rows for k in ("psnr_linear", "pu21_psnr", "psnr_mu"))
    assert "| mine |" in (evaluation / "summary.md").read_text() and (evaluation / "examples.jpg").is_file()
    capsys.readouterr()
    assert main(["evaluate", "--checkpoint", str(run / "model.pt"), "--size", "32", "--count", "2",
                 "--out", str(evaluation)]) == 1  # never overwrites
    _one_line_error(capsys, "already exists")
    fine = tmp_path / "fine"
    assert main(["finetune", "--no-check", "--checkpoint", str(run / "model.pt"),
                 "--psf", "calibration/simulated-rank1/psf.exr",
                 *TINY, "--out", str(fine)]) == 0
    assert load_model(fine / "model.pt").psf.shape == (3, 63, 63)
    capsys.readouterr()
    assert main(["finetune", "--psf", str(tmp_path / "missing.exr"), *TINY, "--out", str(tmp_path / "f2")]) == 1
    _one_line_error(capsys, "does not exist")


def test_paper_preset_without_vgg_weights_stops_with_one_line(tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("HDRCAM_VGG19_WEIGHTS", raising=False)
    assert main(["design", "--preset", "paper", *TINY, "--out", str(tmp_path / "paper")]) == 1
    _one_line_error(capsys, "needs VGG-19 weights")


@pytest.fixture(scope="module")
def night_frame(tmp_path_factory):
    folder = tmp_path_factory.mktemp("night")
    assert main(["simulate", "night", "--size", "96", "160", "--seed", "2", "--out", str(folder / "frame.exr"),
                 "--truth", str(folder / "truth.exr")]) == 0
    return folder


def test_simulate_renders_a_clipped_frame_and_its_truth(night_frame):
    frame, truth = read_exr(night_frame / "frame.exr").rgb(), read_exr(night_frame / "truth.exr").rgb()
    assert frame.shape == truth.shape == (96, 160, 3)
    assert frame.min() >= 0.0 and frame.max() <= 1.0 and truth.max() > 1.0
    assert np.mean(truth.max(axis=-1) > 1.0) == pytest.approx(0.015, abs=2 / truth[..., 0].size)


def test_reconstruct_writes_hdr_mask_confidence_and_previews(night_frame, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["reconstruct", str(night_frame / "frame.exr"), "--out", str(out)]) == 0
    report = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    result = read_exr(out / "frame.exr")
    assert set(result.channels) == {"R", "G", "B", "unreliable", "confidence"} and np.isfinite(result.rgb()).all()
    assert result.rgb().shape == (96, 160, 3) and (out / "frame.png").is_file()
    assert (out / "frame-confidence.png").is_file()
    confidence = result.channels["confidence"]
    frame = read_exr(night_frame / "frame.exr").rgb()
    assert confidence.min() >= 0.0 and confidence.max() <= 1.0
    assert np.all(confidence[frame.max(axis=-1) < 0.99] == 1.0)  # what the frame recorded is never doubted
    assert "windows in 4 passes (the frame and its mirror image, each through 2 networks)" in report["work"]
    assert 0.0 <= report["fallback_fraction"] <= 1.0
    assert result.attributes["fallback_fraction"] == pytest.approx(report["fallback_fraction"], abs=1e-6)
    before = (out / "frame.exr").read_bytes()
    assert main(["reconstruct", str(night_frame / "frame.exr"), "--out", str(out)]) == 1
    _one_line_error(capsys, "already exists")
    assert (out / "frame.exr").read_bytes() == before


def test_reconstruct_reports_a_hot_pixel_as_a_sensor_defect_and_keeps_it_white(night_frame, tmp_path, capsys):
    """The night frame with its darkest pixel (away from the border) forced to white, as a hot pixel reads."""
    frame = read_exr(night_frame / "frame.exr").rgb()
    inner = frame[8:-8, 8:-8].max(axis=-1)
    row, column = np.unravel_index(np.argmin(inner), inner.shape)
    hot = (row + 8, column + 8)
    assert frame[hot].max() < 0.02
    frame[hot] = 1.0
    write_exr(tmp_path / "hot.exr", frame)
    assert main(["reconstruct", str(tmp_path / "hot.exr"), "--out", str(tmp_path / "out")]) == 0
    captured = capsys.readouterr()
    report = json.loads(captured.out.strip().splitlines()[-1])
    assert report["sensor_defect_pixels"] == 1 and "no light can explain" in report["consistency"]
    assert "no light can explain" in captured.err
    np.testing.assert_array_equal(read_exr(tmp_path / "out" / "hot.exr").rgb()[hot], 1.0)


def test_reconstruct_takes_any_tile_and_halo_and_scores_alike(night_frame, tmp_path):
    """Tiles are resized internally to the network's multiple of 16: odd sizes work and score alike."""
    outputs = []
    for tile, halo in (("512", "32"), ("50", "13")):
        out = tmp_path / f"tile{tile}"
        assert main(["reconstruct", str(night_frame / "frame.exr"), "--out", str(out), "--no-adaptive",
                     "--tile", tile, "--halo", halo]) == 0
        outputs.append(read_exr(out / "frame.exr").rgb())
    truth = read_exr(night_frame / "truth.exr").rgb()
    scores = [psnr_linear(output, truth) for output in outputs]
    assert outputs[1].shape == truth.shape and np.isfinite(outputs[1]).all()
    assert abs(scores[0] - scores[1]) < 1.0


def test_reconstruct_without_the_mirror_check_runs_one_pass_per_network(night_frame, tmp_path, capsys):
    assert main(["reconstruct", str(night_frame / "frame.exr"), "--out", str(tmp_path / "pair"),
                 "--no-mirror-check"]) == 0
    report = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert "in 2 passes (through 2 networks)" in report["work"]
    assert read_exr(tmp_path / "pair" / "frame.exr").attributes["partner"].endswith("simulated-rank1-fast-partner.pt")
    assert main(["reconstruct", str(night_frame / "frame.exr"), "--out", str(tmp_path / "one"), "--no-mirror-check",
                 "--no-partner"]) == 0
    report = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert "windows" in report["work"] and "passes" not in report["work"]
    result = read_exr(tmp_path / "one" / "frame.exr")
    assert np.isfinite(result.rgb()).all() and result.attributes["partner"] == "none"


def test_reconstruct_places_highlights_only_on_request_and_says_why_not(night_frame, tmp_path, capsys):
    assert main(["reconstruct", str(night_frame / "frame.exr"), "--out", str(tmp_path / "plain")]) == 0
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1])["placement"] == "off"
    assert main(["reconstruct", str(night_frame / "frame.exr"), "--out", str(tmp_path / "placed"),
                 "--place-highlights"]) == 0
    report = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert report["placement"].startswith("highlight placement: not run")  # the shipped DOE's streaks end at 44 px
    np.testing.assert_array_equal(read_exr(tmp_path / "placed" / "frame.exr").rgb(),
                                  read_exr(tmp_path / "plain" / "frame.exr").rgb())


def test_reconstruct_reads_16_bit_tiff(tmp_path):
    frame = (np.random.default_rng(0).random((40, 50, 3)) * 0.5 * 65535).astype(np.uint16)
    frame[10, 10] = 65535
    cv2.imwrite(str(tmp_path / "frame.tif"), frame)
    assert main(["reconstruct", str(tmp_path / "frame.tif"), "--out", str(tmp_path / "out")]) == 0
    assert read_exr(tmp_path / "out" / "frame.exr").rgb().shape == (40, 50, 3)


def test_reconstruct_bad_inputs_are_one_line_errors(tmp_path, capsys):
    nan = np.full((32, 32, 3), 0.5, np.float32)
    nan[3, 3, 1] = np.nan
    OpenEXR.File({"type": OpenEXR.scanlineimage}, {"RGB": nan}).write(str(tmp_path / "nan.exr"))
    write_exr(tmp_path / "hdr.exr", np.full((32, 32, 3), 300.0, np.float32))
    cv2.imwrite(str(tmp_path / "eight.png"), np.zeros((8, 8, 3), np.uint8))
    (tmp_path / "damaged.exr").write_bytes(b"v/1\x01" + b"\x00" * 40)
    cases = {"nan.exr": "NaN or Inf", "hdr.exr": "not an LDR capture", "eight.png": "gamma-encoded",
             "missing.exr": "does not exist", "damaged.exr": "damaged.exr"}
    for name, message in cases.items():
        assert main(["reconstruct", str(tmp_path / name), "--out", str(tmp_path / "out")]) == 1, name
        _one_line_error(capsys, message)
    assert not (tmp_path / "out").exists()
    assert main(["reconstruct", str(tmp_path / "hdr.exr"), "--precision", "float16", "--device", "cpu",
                 "--out", str(tmp_path / "out")]) == 1
    _one_line_error(capsys, "on the CPU runs many times slower")  # hdrcam.api.checked_device's refusal


def test_demo_runs_the_whole_chain(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--finetune-steps", "1", "--size", "128", "192"]) == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert set(summary["psnr_linear_db"]) == {"ldr", "reconstruction"}
    assert all(np.isfinite(v) for v in summary["psnr_linear_db"].values())
    for name in ("index.md", "3-calibration/psf.exr", "4-finetune/model.pt", "6-reconstruction/5-night-frame.exr",
                 "preview-reconstruction.png", "2-calibration-fused.exr"):
        assert (out / name).is_file(), name
    assert "`4-finetune/` (model.pt" in (out / "index.md").read_text()
    assert main(["demo", "--out", str(out)]) == 1  # never overwrites a finished demo
    _one_line_error(capsys, "not empty")


def test_the_demo_index_lists_no_finetune_folder_when_none_was_made():
    from hdrcam.cli.demo_command import _index

    scores = {"ldr": {"psnr_linear": 30.0, "pu21_psnr": 20.0, "psnr_mu": 25.0}}
    index = _index(scores, {"capture": 1.0}, 10.0, SHIPPED_CHECKPOINT, [0.01, 0.02, 0.03], None, finetuned=False)
    assert "4-finetune" not in index  # --finetune-steps 0 listed a folder it never made


def test_exports_agree_with_the_torch_path(night_frame, tmp_path, capsys):
    pytest.importorskip("onnxruntime")
    assert main(["export", "--format", "torchscript", "--out", str(tmp_path / "net.pt")]) == 0
    assert main(["export", "--format", "onnx", "--out", str(tmp_path / "net.onnx")]) == 0
    import torch

    model = load_model()
    frame = torch.from_numpy(read_exr(night_frame / "frame.exr").rgb()).permute(2, 0, 1)[None]
    with torch.no_grad():
        reference = model.network(frame).hdr
        scripted = torch.jit.load(str(tmp_path / "net.pt"))(frame)
    assert torch.allclose(scripted, reference, rtol=1e-5, atol=1e-5)
    for checkpoint, name in ((None, "torch"), (tmp_path / "net.onnx", "onnx")):
        argv = ["reconstruct", str(night_frame / "frame.exr"), "--out", str(tmp_path / name), "--no-partner"]
        assert main(argv + (["--checkpoint", str(checkpoint)] if checkpoint else [])) == 0
    torch_hdr = read_exr(tmp_path / "torch" / "frame.exr").rgb()
    onnx_hdr = read_exr(tmp_path / "onnx" / "frame.exr").rgb()
    # onnxruntime's kernels round differently; InstanceNorm and the exp() of the fusion amplify it a little
    from hdrcam.evaluate.metrics import psnr_linear

    assert psnr_linear(onnx_hdr, torch_hdr) > 80.0
    relative = np.abs(onnx_hdr - torch_hdr) / np.maximum(np.abs(torch_hdr), 1e-2)
    assert np.mean(relative > 1e-2) < 1e-2  # measured: 0.03 % (1000-step network), 0.18 % (shipped)
    capsys.readouterr()
    assert main(["export", "--format", "onnx", "--out", str(tmp_path / "net.onnx")]) == 1
    _one_line_error(capsys, "already exists")


def test_destreak_trains_on_windshield_streaks_and_removes_them(tmp_path, capsys, night_frame):
    from hdrcam.train.optical_capture import _windshield_angle_deg

    import torch

    generator = torch.Generator().manual_seed(0)
    angles = [_windshield_angle_deg(generator) for _ in range(200)]
    assert all(2.5 <= abs(a) <= 8.0 for a in angles) and min(angles) < 0 < max(angles)
    run = tmp_path / "windshield"
    assert main(["design", "--psf", "windshield", *TINY, "--out", str(run)]) == 0
    out = tmp_path / "clean"
    assert main(["destreak", str(night_frame / "frame.exr"), "--method", "network", "--checkpoint",
                 str(run / "model.pt"), "--out", str(out)]) == 0
    clean = read_exr(out / "frame.exr").rgb()
    assert clean.shape == (96, 160, 3) and clean.min() >= 0.0 and clean.max() <= 1.0
    capsys.readouterr()
    other = tmp_path / "other"
    assert main(["design", "--psf", "dirac", *TINY, "--out", str(other)]) == 0
    capsys.readouterr()
    assert main(["destreak", str(night_frame / "frame.exr"), "--method", "network", "--checkpoint",
                 str(other / "model.pt"), "--out", str(tmp_path / "o")]) == 1
    _one_line_error(capsys, "not trained on windshield streaks")


def test_destreak_by_streak_fit_is_the_default_and_never_overwrites(tmp_path, capsys, night_frame):
    out = tmp_path / "clean"
    assert main(["destreak", str(night_frame / "frame.exr"), "--out", str(out)]) == 0
    printed = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert "work" in printed and read_exr(out / "frame.exr").rgb().shape == (96, 160, 3)
    before = (out / "frame.exr").read_bytes()
    assert main(["destreak", str(night_frame / "frame.exr"), "--out", str(out)]) == 1
    _one_line_error(capsys, "already exists")
    assert (out / "frame.exr").read_bytes() == before


def test_damaged_raw_gives_exactly_one_line_on_stderr(tmp_path):
    """LibRaw's own C-level message is silenced: the user sees hdrcam's line only."""
    import subprocess
    import sys

    from hdrcam.capture.backends import open_camera
    from hdrcam.capture.bracket import BracketCapture, BracketPlan
    from hdrcam.capture.scene import load_scene
    from hdrcam.optics.analytic import dirac
    from hdrcam.profiles import load_profile

    profile = load_profile("simulated")
    camera, _ = open_camera("sim", profile, scene=load_scene("night", 64, 96), psf=dirac(9))
    with camera:
        bracket = BracketCapture(camera, profile.camera, tmp_path / "b", backend="sim", profile="simulated",
                                 show_progress=False).shoot(BracketPlan(shortest_s=1 / 250, stops=1, ev_step=3.0,
                                                                        iso=100.0))
    frame = tmp_path / "b" / bracket.frames[0].file
    (tmp_path / "cut.dng").write_bytes(frame.read_bytes()[:5000])
    result = subprocess.run([sys.executable, "-m", "hdrcam", "reconstruct", str(tmp_path / "cut.dng"), "--out",
                             str(tmp_path / "out")], capture_output=True, text=True)
    assert result.returncode == 1 and result.stderr.count("\n") == 1 and "cut.dng: truncated" in result.stderr
    good = subprocess.run([sys.executable, "-m", "hdrcam", "reconstruct", str(frame), "--out", str(tmp_path / "ok")],
                          capture_output=True, text=True)
    assert good.returncode == 0 and (tmp_path / "ok" / f"{frame.stem}.exr").is_file()


def test_reconstruct_refuses_inputs_whose_outputs_collide_before_writing_anything(night_frame, tmp_path, capsys):
    """'frame' writes frame-confidence.png, and so does an input named 'frame-confidence'; two inputs called
    'frame' in different folders write the same frame.exr. Both are refused with one line, and nothing is written."""
    other = tmp_path / "frame-confidence.exr"
    other.write_bytes((night_frame / "frame.exr").read_bytes())
    twin = tmp_path / "twin"
    twin.mkdir()
    (twin / "frame.exr").write_bytes((night_frame / "frame.exr").read_bytes())
    for pair in ((night_frame / "frame.exr", other), (night_frame / "frame.exr", twin / "frame.exr")):
        out = tmp_path / f"out-{pair[1].parent.name}"
        assert main(["reconstruct", str(pair[0]), str(pair[1]), "--out", str(out)]) == 1
        _one_line_error(capsys, "would both write")
        assert not out.exists() or not any(out.iterdir())


def test_destreak_names_the_two_inputs_whose_outputs_collide(tmp_path, capsys):
    frame = np.full((16, 16, 3), 0.5, np.float32)
    for folder in ("a", "b"):
        (tmp_path / folder).mkdir()
        write_exr(tmp_path / folder / "frame.exr", frame)
    first, second = tmp_path / "a" / "frame.exr", tmp_path / "b" / "frame.exr"
    assert main(["destreak", str(first), str(second), "--out", str(tmp_path / "out")]) == 1
    error = capsys.readouterr().err.strip()  # it named one output twice, not the inputs
    assert error.count("\n") == 0 and f"{second} and {first} would both write" in error
    assert not (tmp_path / "out").exists()


def test_destreak_names_an_input_given_twice(tmp_path, capsys):
    frame = write_exr(tmp_path / "frame.exr", np.full((16, 16, 3), 0.5, np.float32))
    assert main(["destreak", str(frame), str(frame), "--out", str(tmp_path / "out")]) == 1
    error = capsys.readouterr().err.strip()
    assert error.count("\n") == 0 and f"{frame} is given twice" in error


def test_destreak_records_an_angle_only_where_it_removed_streaks_and_refuses_a_device_for_the_fit(tmp_path,
                                                                                                   capsys):
    """A frame without streaks recorded the best fit's angle (3.50) in its EXR as if streaks at 3.5 deg had been
    subtracted; --device cuda was taken and ignored by the fit, which runs on the CPU."""
    frame = np.full((64, 64, 3), 0.2, np.float32)
    frame[30:33, 30:33] = 1.0  # a clipped light, no streak
    source = write_exr(tmp_path / "clear.exr", frame)
    assert main(["destreak", str(source), "--out", str(tmp_path / "out")]) == 0
    attributes = read_exr(tmp_path / "out" / "clear.exr").attributes
    assert attributes["angle_deg"] == "none" and attributes["clusters_destreaked"] == "0 of 1"
    capsys.readouterr()
    assert main(["destreak", str(source), "--device", "cuda", "--out", str(tmp_path / "other")]) == 1
    _one_line_error(capsys, "--device cuda applies only to --method network")


def test_reconstruct_prints_its_warning_on_a_line_of_its_own(tmp_path):
    """The clipped-streak warning came out where the progress bar ended ("... 5.26window/s]hdrcam: warning:")."""
    import torch

    from hdrcam.optics.analytic import star
    from hdrcam.sensor import fft_convolve

    psf = star(63, points=8)
    scene = np.full((3, 160, 160), 0.1, np.float32)
    scene[:, 80:83, 80:83] = 1e4  # its eight streaks clip
    frame = fft_convolve(torch.from_numpy(scene), torch.from_numpy(psf)).clamp(0, 1).permute(1, 2, 0).numpy()
    write_exr(tmp_path / "frame.exr", np.ascontiguousarray(frame))
    write_exr(tmp_path / "psf.exr", np.ascontiguousarray(psf.transpose(1, 2, 0)))
    command = [sys.executable, "-m", "hdrcam", "reconstruct", str(tmp_path / "frame.exr"), "--psf",
               str(tmp_path / "psf.exr"), "--no-partner", "--no-mirror-check", "--out", str(tmp_path / "out")]
    done = subprocess.run(command, capture_output=True, text=True, timeout=300)  # pytest would keep the warning
    assert done.returncode == 0, done.stderr
    error = done.stderr
    start = error.index("hdrcam: warning: frame.exr:")
    assert error[start - 1] in "\r\n", repr(error[max(start - 40, 0):start + 30])
