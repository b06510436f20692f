"""The public API's inputs that the command line's parsers never pass: PSFs that are not unit-sum intensities,
empty frames, window sizes, training settings and brackets that cannot work, a bracket given as one path."""

from __future__ import annotations

import numpy as np
import pytest

import hdrcam
from hdrcam.errors import InputError
from hdrcam.train.checkpoint import load_model


@pytest.fixture(scope="module")
def model():
    return load_model()


def _frame() -> np.ndarray:
    frame = np.full((64, 64, 3), 0.05, np.float32)
    frame[28:36, 28:36] = 1.0
    return frame


def test_a_psf_in_counts_gives_what_its_unit_sum_gives(model):
    unit = hdrcam.reconstruct(_frame(), model, psf=model.psf, partner=None, mirror_check=False)
    counts = hdrcam.reconstruct(_frame(), model, psf=model.psf * 5000.0, partner=None, mirror_check=False)
    assert np.array_equal(unit.hdr, counts.hdr)


@pytest.mark.parametrize("psf, message", [(-1.0, "not an intensity"), (0.0, "not an intensity"),
                                          (np.nan, "NaN or Inf"), ("2d", "3 x k x k")])
def test_psfs_that_are_not_intensities_are_refused(model, psf, message):
    shaped = model.psf[0] if psf == "2d" else model.psf * psf
    with pytest.raises(InputError, match=message):
        hdrcam.reconstruct(_frame(), model, psf=shaped, partner=None)


@pytest.mark.parametrize("options, message", [({"tile_px": 0}, "at least 16"), ({"tile_px": 1}, "at least 16"),
                                              ({"halo_px": -1}, "0 or more")])
def test_window_sizes_that_cannot_work_are_refused(model, options, message):
    with pytest.raises(InputError, match=message):
        hdrcam.reconstruct(_frame(), model, partner=None, **options)


def test_an_empty_frame_is_refused_as_a_frame_error_that_is_also_a_value_error(model):
    with pytest.raises(ValueError, match="H, W >= 1"):
        hdrcam.reconstruct(np.zeros((0, 0, 3), np.float32), model, partner=None)
    with pytest.raises(InputError):
        hdrcam.reconstruct(np.zeros((0, 0, 3), np.float32), model, partner=None)


@pytest.mark.parametrize("options, message", [
    ({"steps": 0}, "steps must be a whole number, 1 or more"), ({"batch": 0}, "batch must be"),
    ({"learning_rate": -1.0}, "learning_rate must be a positive, finite number"),
    ({"learning_rate": float("nan")}, "learning_rate must be"), ({"checkpoint_every": 0}, "checkpoint_every"),
    ({"seed": -1}, "seed must be a whole number from 0"), ({"doe": "nope"}, "doe must be one of rank1, freeform")])
def test_training_settings_no_run_can_have_are_refused_before_anything_is_written(tmp_path, options, message):
    with pytest.raises(InputError, match=message):
        hdrcam.design(tmp_path / "run", **options)
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("options, message", [({"stops": 0}, "stops 0: a bracket takes"),
                                              ({"ev_step": 0}, "ev_step must be a positive multiple"),
                                              ({"shortest_s": float("nan")}, "a shutter time is a positive"),
                                              ({"exposure_error": 5.0}, "exposure_error 5.0: expected a fraction"),
                                              ({"hot_pixel_fraction": -1.0}, "hot_pixel_fraction"),
                                              ({"iso": float("nan")}, "ISO nan: the camera's settings are")])
def test_brackets_no_camera_can_take_are_refused_before_the_folder_is_claimed(tmp_path, options, message):
    with pytest.raises(InputError, match=message):
        hdrcam.capture_bracket(tmp_path / "b", camera="sim", profile="simulated", psf="dirac", size_px=(64, 48),
                               **options)
    assert not (tmp_path / "b").exists()


def test_a_bracket_given_as_one_path_is_fused_as_its_list_is(tmp_path):
    hdrcam.capture_bracket(tmp_path / "b", camera="sim", profile="simulated", psf="dirac", size_px=(64, 48),
                           stops=2, scene="flat:0.5")
    for bracket in (str(tmp_path / "b"), tmp_path / "b"):
        assert np.array_equal(hdrcam.fuse(bracket, profile="simulated").rgb,
                              hdrcam.fuse([tmp_path / "b"], profile="simulated").rgb)
    with pytest.raises(InputError, match="PSF size 4: an odd number of pixels"):
        hdrcam.calibrate_psf(tmp_path / "b", profile="simulated", size_px=4)


@pytest.mark.parametrize("options, message", [({"size_px": 0}, "multiple of 16 and at least 32"),
                                              ({"size_px": 100}, "multiple of 16"),
                                              ({"count": 0}, "count must be a whole number"),
                                              ({"checkpoints": ["model.pt"]}, "a dict of label")])
def test_test_sets_that_cannot_be_scored_are_refused(options, message):
    with pytest.raises(InputError, match=message):
        hdrcam.evaluate_checkpoints(**options)


def test_a_photograph_without_light_is_left_out_of_evaluate_by_name_and_the_others_keep_their_noise(tmp_path):
    from hdrcam.io.exr import write_exr

    lamp = np.linspace(0, 1, 64 * 64 * 3, dtype=np.float32).reshape(64, 64, 3)
    write_exr(tmp_path / "lamp.exr", lamp)
    rows_alone, _ = hdrcam.evaluate_checkpoints(data=str(tmp_path), size_px=32)
    write_exr(tmp_path / "a-lens-cap.exr", np.zeros((64, 64, 3), np.float32))  # sorted first: lamp moves to index 1
    write_exr(tmp_path / "b-lamp.exr", lamp)
    (tmp_path / "lamp.exr").unlink()
    with pytest.warns(UserWarning, match="a-lens-cap: not scored"):  # the run failed: 'image has no light'
        rows, _ = hdrcam.evaluate_checkpoints(data=str(tmp_path), size_px=32)
    assert {row.image for row in rows} == {"b-lamp"}
    ldr = [row.metrics["psnr_linear"] for row in rows + rows_alone if row.method == "ldr"]
    assert ldr[0] != ldr[1]  # index 1's noise draw, not index 0's: the file kept its place


def test_a_folder_given_as_a_frame_is_named_as_a_folder(tmp_path):
    from hdrcam.io.ldr_frame import read_ldr_frame

    with pytest.raises(InputError, match="is a folder; give the frames in it"):
        read_ldr_frame(tmp_path)


def test_files_where_arrays_belong_windshield_networks_and_unusable_devices_are_input_errors(model, tmp_path):
    """A notebook user got numpy's 'could not convert string to float' for a frame's path, an AttributeError for a
    checkpoint's path, a silent no-op from the windshield network the CLI refuses, torch's AssertionError for
    device='cuda' without CUDA, float16 on the CPU at 7 x float32's time, and an AttributeError for noise=25000;
    tile_px=np.int64(256) was refused as not a whole number."""
    import torch

    from hdrcam.train.checkpoint import SHIPPED_CHECKPOINT

    frame = _frame()
    for arguments, message in (((str(tmp_path / "frame.exr"),), "frame is an array or a model, not a file"),
                               ((frame, "model.pt"), "model is an array or a model, not a file")):
        with pytest.raises(InputError, match=message):
            hdrcam.reconstruct(*arguments)
    with pytest.raises(InputError, match="psf is an array or a model, not a file"):
        hdrcam.reconstruct(frame, model, psf=tmp_path / "psf.exr")
    with pytest.raises(InputError, match="a windshield network"):
        hdrcam.reconstruct(frame, load_model(SHIPPED_CHECKPOINT.parent / "windshield-fast.pt"))
    if not torch.cuda.is_available():
        with pytest.raises(InputError, match="torch sees no CUDA device"):
            hdrcam.reconstruct(frame, model, device="cuda")
    with pytest.raises(InputError, match="device 'gpu'"):
        hdrcam.reconstruct(frame, model, device="gpu")
    with pytest.raises(InputError, match="on the CPU runs many times slower"):
        hdrcam.reconstruct(frame, model, dtype=torch.float16)
    with pytest.raises(InputError, match="noise 25000: a hdrcam.recon.consistency.NoiseModel"):
        hdrcam.reconstruct(frame, model, noise=25000)
    assert hdrcam.reconstruct(frame, model, tile_px=np.int64(256), partner=None).hdr.shape == frame.shape
    with pytest.raises(InputError, match="finetune's psf is a file, not a ndarray"):
        hdrcam.finetune(np.ones((3, 5, 5)), tmp_path / "run")


def test_the_command_lines_spellings_given_to_capture_and_fuse_are_input_errors(tmp_path):
    """camera='Sim' was a ValueError, shortest_s='1/4000' and size_px=64 TypeErrors from deep in the plan, and
    fuse's demosaic='edge-aware' a ValueError that named it as a choice."""
    for arguments, message in ((dict(camera="Sim"), "unknown camera 'Sim'"),
                               (dict(shortest_s="1/4000"), "shortest_s is a number"),
                               (dict(ev_step="2/3", stops=3), "ev_step is a number"),
                               (dict(size_px=64), r"size_px is \(width, height\)")):
        with pytest.raises(InputError, match=message):
            hdrcam.capture_bracket(tmp_path / "bracket", **arguments)
    with pytest.raises(InputError, match="fuse's demosaic 'edge-aware': one of bilinear, menon2007"):
        hdrcam.fuse([tmp_path / "bracket"], demosaic="edge-aware")


def test_capture_sizes_are_read_as_whole_pixels_and_a_number_alone_is_refused_in_one_line(tmp_path):
    """np.int64(64) and 64.0 made the size check itself raise a bare TypeError ('has no len()'); a numpy pair
    passed it and failed later on its truth value."""
    for size in (np.int64(64), 64.0, "64x48", (64,)):
        with pytest.raises(InputError, match=r"size_px is \(width, height\) in whole pixels"):
            hdrcam.capture_bracket(tmp_path / "bracket", size_px=size)
    bracket, _ = hdrcam.capture_bracket(tmp_path / "bracket", size_px=np.array([96, 64]), stops=2)
    assert bracket.status == "complete"
