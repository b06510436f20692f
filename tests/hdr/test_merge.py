"""The bracket merge against ground truth: radiance error vs an oracle merge, ratio estimation, bad input."""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np
import pytest

from hdrcam.capture.backends import open_camera
from hdrcam.capture.bracket import BracketCapture, BracketPlan
from hdrcam.capture.scene import Scene, load_scene
from hdrcam.cli import main
from hdrcam.errors import InputError
from hdrcam.hdr.bracket_input import read_bracket
from hdrcam.hdr.fuse import fuse
from hdrcam.hdr.merge import merge_bayer
from hdrcam.optics.analytic import dirac
from hdrcam.profiles import load_profile

PROFILE = load_profile("simulated")
TRUE_SHORTEST_S = 2.0 ** -12  # the true time of the 1/4000 notch; labels off the nominal series are taken as given


def capture(folder: Path, scene: Scene | str = "night", *, seed=0, exposure_error=0.0, iso=100.0, stops=5,
            shortest=1 / 4000, dark=False, size=(96, 128)):
    scene = scene if isinstance(scene, Scene) else load_scene(scene, *size, seed=seed)
    camera, simulated = open_camera("sim", PROFILE, scene=scene, psf=dirac(9), seed=seed,
                                    exposure_error=exposure_error, hot_pixel_fraction=0.0)
    with camera:
        capture = BracketCapture(camera, PROFILE.camera, folder, backend="sim", profile="simulated",
                                 show_progress=False, true_exposure_s=simulated.true_exposure_s)
        plan = BracketPlan(shortest_s=shortest, stops=stops, ev_step=3.0, iso=iso)
        bracket = capture.shoot(plan)
    truth = simulated._rate(False) / simulated.reference_exposure_s  # full wells per second, Bayer
    return bracket, truth


def relative_rms(estimate, truth, mask):
    return float(np.sqrt(np.mean(((estimate - truth) / truth)[mask] ** 2)))


def test_merge_is_within_10_percent_of_an_oracle_that_knows_the_true_exposures(tmp_path):
    """Scene spans 0.005 .. 256 relative radiance (> 1e4:1) plus the zero-noise floor; 7 % label errors.
    (Seed 4: since night scenes gained lit signs, seed 3's 96 x 128 crop spans only 6.4e3:1.)"""
    bracket, truth = capture(tmp_path, seed=4, exposure_error=0.07)
    frames = read_bracket([tmp_path])
    merged = merge_bayer(frames, PROFILE.camera)
    true_exposures = np.array([f.true_exposure_s for f in bracket.frames])
    oracle = merge_bayer([_relabelled(f, t) for f, t in zip(frames, true_exposures)], PROFILE.camera,
                         estimate_ratios=False)
    valid = ~merged.clipped_everywhere & (truth > 0)
    error, oracle_error = relative_rms(merged.rate, truth, valid), relative_rms(oracle.rate, truth, valid)
    assert error <= 1.10 * oracle_error
    assert truth[valid].max() / truth[valid].min() > 1e4


def _relabelled(frame, exposure_s):
    import dataclasses

    return dataclasses.replace(frame, metadata=dataclasses.replace(frame.metadata, exposure_s=exposure_s))


@pytest.mark.parametrize("seed", [1, 2])
def test_ratios_are_recovered_within_half_a_percent_from_labels_off_by_7_percent(tmp_path, seed):
    bracket, _ = capture(tmp_path, seed=seed, exposure_error=0.07)
    merged = merge_bayer(read_bracket([tmp_path]), PROFILE.camera)
    true = np.array([f.true_exposure_s for f in bracket.frames])
    labelled_error = np.abs(np.diff(np.log(merged.labelled_exposures_s)) - np.diff(np.log(true))).max()
    estimated_error = np.abs(np.diff(np.log(merged.exposures_s)) - np.diff(np.log(true))).max()
    assert labelled_error > 0.02 and estimated_error < 0.005



@pytest.mark.parametrize("iso", [6400, 25600])
def test_ratios_at_high_iso_are_not_biased_by_selecting_on_the_samples_own_noise(tmp_path, iso):
    """At ISO 25600 the bound on the shorter frame is a few electrons: bounding the sample itself dropped those
    that read high and gave +114 % for this pair (+436 % on a 96 x 128 crop); its neighbours' mean gives -2.1 %."""
    bracket, _ = capture(tmp_path, seed=0, iso=iso, size=(192, 256))
    merged = merge_bayer(read_bracket([tmp_path]), PROFILE.camera)
    true = np.array([f.true_exposure_s for f in bracket.frames])
    error = np.diff(np.log(merged.exposures_s)) - np.diff(np.log(true))
    assert "from" in merged.notes[0] and abs(error[0]) < 0.035
    if iso == 6400:  # +12 % before
        assert "from" in merged.notes[1] and abs(error[1]) < 0.01


def _with_black(frame, shift_dn: float):
    import dataclasses

    meta = frame.metadata
    return dataclasses.replace(frame, metadata=dataclasses.replace(
        meta, black_level_dn=tuple(b + shift_dn for b in meta.black_level_dn)))


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_black_level_one_dn_off_moves_neither_the_ratios_nor_the_scale(tmp_path, seed):
    """Bodies declare black to within a DN or so; the shortest frame of a night bracket is a few DN above it, so
    a ratio of sums moved by that DN over its mean signal: +5.4..+8.8 % (pair 0) and a scale 1.5-2.6 % off
    for +-1 DN on these crops. The slope against a third frame cancels any offset."""
    bracket, truth = capture(tmp_path, seed=seed)
    frames = read_bracket([tmp_path])
    true = np.array([f.true_exposure_s for f in bracket.frames])
    reference = merge_bayer(frames, PROFILE.camera)
    for shift in (1.0, -1.0):
        merged = merge_bayer([_with_black(frame, shift) for frame in frames], PROFILE.camera)
        moved = np.diff(np.log(merged.exposures_s)) - np.diff(np.log(reference.exposures_s))
        assert np.abs(moved).max() < 0.002, (shift, moved)
        valid = ~merged.clipped_everywhere & (truth > 0.05)
        assert abs(np.median(merged.rate[valid] / truth[valid]) - 1) < 0.005
    assert np.abs(np.diff(np.log(reference.exposures_s)) - np.diff(np.log(true))).max() < 0.012


def test_data_clipped_at_a_black_level_of_0_keep_their_ratios(tmp_path):
    """A body that subtracts black in camera (black level 0) clips the noise of dim samples at 0 DN, which lifts
    their mean: pair 0 read 1.4-2.5 % low at ISO 800. Only samples 2 read-noise sigmas clear of the ADC's zero
    count."""
    import dataclasses

    bracket, _ = capture(tmp_path, seed=1, iso=800)
    frames = read_bracket([tmp_path])
    clipped = [dataclasses.replace(
        frame, bayer_dn=np.clip(frame.bayer_dn.astype(np.int32) - 512, 0, None).astype(np.uint16),
        metadata=dataclasses.replace(frame.metadata, black_level_dn=(0.0,) * 4,
                                     white_level_dn=frame.metadata.white_level_dn - 512)) for frame in frames]
    true = np.array([f.true_exposure_s for f in bracket.frames])
    error = np.diff(np.log(merge_bayer(clipped, PROFILE.camera).exposures_s)) - np.diff(np.log(true))
    assert np.abs(error).max() < 0.012, error


def test_a_ratio_far_from_its_label_is_used_and_warned_about(tmp_path):
    """A frame labelled a stop off (bulb, a rounded long exposure): the data's ratio is used, and said to differ."""
    bracket, _ = capture(tmp_path, seed=2)
    frames = read_bracket([tmp_path])
    frames[-1] = _relabelled(frames[-1], frames[-1].metadata.exposure_s * 2)
    expected = r"frames 3-4: their data give an exposure ratio of ([\d.]+) where the labels say 16 \(-1\.0 stops\)"
    with pytest.warns(UserWarning, match=expected) as warned:
        merged = merge_bayer(frames, PROFILE.camera)
    true = np.array([f.true_exposure_s for f in bracket.frames])
    # the ratio said is the one used, within 1 % of the truth (8): not its digits, which move with the machine
    # (below 8 where the test was written, 8.004 on an AMD EPYC with the same packages)
    said = float(re.search(expected, str(warned[0].message)).group(1))
    assert said == pytest.approx(merged.exposures_s[4] / merged.exposures_s[3], rel=1e-3)
    assert abs(np.log(merged.exposures_s[4] / merged.exposures_s[3] / (true[4] / true[3]))) < 0.01


def test_a_samples_neighbour_mean_leaves_the_sample_out_at_the_edges_too():
    from hdrcam.hdr.neighbour_mean import neighbour_mean

    impulses = np.zeros((12, 12), np.float32)
    for row, column in ((1, 3), (1, 1), (0, 0), (6, 6), (11, 10)):
        impulses[row, column] = 1.0
    own = neighbour_mean(impulses * 100.0)
    lone = neighbour_mean(np.pad(np.ones((1, 1), np.float32) * 100.0, ((6, 5), (6, 5))))
    assert lone[6, 6] == 0.0 and lone[4, 4] == pytest.approx(100.0 / 8)  # inside: eight neighbours
    for row, column in ((1, 1), (0, 0), (11, 10)):  # mirrored edges put a sample into its own mean
        others = [impulses[r, c] * 100.0 for r in (row - 2, row, row + 2) for c in (column - 2, column, column + 2)
                  if (r, c) != (row, column) and 0 <= r < 12 and 0 <= c < 12]
        assert own[row, column] == pytest.approx(np.mean(others))
    np.testing.assert_allclose(neighbour_mean(np.full((7, 9), 5.0, np.float32)), 5.0)


def test_refinements_from_the_kept_band_give_what_full_passes_give(tmp_path, monkeypatch):
    """Labels off by 7 %: the default band keeps every refinement's bound inside it (one pass over the data); a band
    of 1e-4 sends every refinement after the first to a full pass, and a band of 100 keeps nearly every pixel.
    All three give the same exposures to 1e-6."""
    import hdrcam.hdr.exposure_ratios as exposure_ratios

    capture(tmp_path, seed=1, exposure_error=0.07)
    frames = read_bracket([tmp_path])
    exposures = {}
    for band in (exposure_ratios.BOUND_BAND, 1.0001, 100.0):
        monkeypatch.setattr(exposure_ratios, "BOUND_BAND", band)
        exposures[band] = merge_bayer(frames, PROFILE.camera).exposures_s
    for band, estimated in exposures.items():
        np.testing.assert_allclose(estimated, exposures[100.0], rtol=1e-6, atol=0, err_msg=f"band {band}")
    assert np.abs(np.log(exposures[100.0] / merge_bayer(frames, PROFILE.camera, estimate_ratios=False).exposures_s)
                  ).max() > 0.02

def test_pixels_clipped_everywhere_carry_a_finite_lower_bound_and_a_flag(tmp_path):
    radiance = np.full((32, 48, 3), 0.2, np.float32)
    radiance[10:14, 10:14] = 1e6  # clipped even at 1/4000 s
    capture(tmp_path, Scene(32, 48, radiance), stops=2)
    image = fuse([tmp_path], PROFILE.camera)
    assert image.clipped[11:13, 11:13].all() and not image.clipped[25:, 30:].any()
    assert np.isfinite(image.rgb).all() and np.isfinite(image.merge.rate).all()
    lower_bound = image.merge.rate[11, 11]
    assert 0 < lower_bound < 1e6 * 60


def test_a_few_lamps_on_black_are_not_taken_for_a_capped_lens(tmp_path):
    import warnings

    capture(tmp_path, "point", stops=3, size=(400, 600))  # one lamp: a few hundred lit samples of 240 000
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        merge_bayer(read_bracket([tmp_path]), PROFILE.camera)
    assert not [w for w in caught if "almost no light" in str(w.message)]  # it asked: dark frames given as lights?


def test_thousands_of_hot_pixels_do_not_pass_for_light():
    from hdrcam.hdr.merge import _clustered

    hot = np.zeros((800, 1200), bool)
    hot.flat[np.random.default_rng(0).choice(hot.size, 4000, replace=False)] = True  # 0.4 %: a long dark frame's
    assert _clustered(hot) == 0  # counted by neighbours within two pixels, 357 of them passed for lamps
    hot[100:102, 200:202] = True  # one lamp's 2 x 2 core
    assert _clustered(hot) >= 4


def test_a_black_scene_merges_to_near_zero_and_stays_finite(tmp_path):
    capture(tmp_path, "flat:0", stops=3, size=(32, 32))
    with pytest.warns(UserWarning, match="recorded almost no light"):  # as dark frames given as lights would
        image = fuse([tmp_path], PROFILE.camera, with_variance=True)
    assert np.isfinite(image.rgb).all() and np.isfinite(image.variance).all()
    noise = np.sqrt(image.variance)  # read noise only: the estimate scatters around zero within it
    assert np.abs(image.rgb.mean()) < 0.2 * noise.mean() and (np.abs(image.rgb) < 6 * noise).all()


def test_fuse_cli_writes_exr_with_mask_and_preview(tmp_path, capsys):
    folder = tmp_path / "bracket"
    capture(folder, "night", stops=3)
    out = tmp_path / "hdr.exr"
    assert main(["fuse", str(folder), "--out", str(out), "--profile", "simulated"]) == 0
    from hdrcam.io.exr import read_exr

    exr = read_exr(out)
    assert set(exr.channels) == {"R", "G", "B", "clipped"} and out.with_suffix(".png").is_file()
    assert "estimated_exposures_s" in exr.attributes
    assert main(["fuse", str(folder), "--out", str(tmp_path / "h.exr"), "--profile", "simulated", "--half"]) == 0
    assert np.allclose(read_exr(tmp_path / "h.exr").rgb(), exr.rgb(), rtol=1e-3, atol=1e-4)
    capsys.readouterr()
    before = out.read_bytes()
    assert main(["fuse", str(folder), "--out", str(out), "--profile", "simulated"]) == 1
    assert "exists" in capsys.readouterr().err and out.read_bytes() == before


def test_half_float_files_keep_the_variance_in_float32(tmp_path):
    """Variances span 1e-8 (dim pixels of long exposures: half stored 0, certainty) to 1e30 (unknown: clipped
    in every frame; half held only 65504): they stay float32, bit for bit, while RGB is rounded to half."""
    from hdrcam.io.exr import read_exr

    bracket = Path(__file__).parent / "data" / "bracket-96x64"
    argv = ["fuse", str(bracket), "--variance", "--profile", "simulated", "--out"]
    assert main(argv + [str(tmp_path / "full.exr")]) == 0 and main(argv + [str(tmp_path / "half.exr"), "--half"]) == 0
    full, half = read_exr(tmp_path / "full.exr"), read_exr(tmp_path / "half.exr")
    assert full.channels["clipped"].any() and (full.channels["variance.G"] >= 1e30).any()
    for channel in ("variance.R", "variance.G", "variance.B"):
        np.testing.assert_array_equal(half.channels[channel], full.channels[channel])
    np.testing.assert_array_equal(half.channels["G"], full.channels["G"].astype(np.float16).astype(np.float32))
    assert not np.array_equal(half.channels["G"], full.channels["G"])
    assert (tmp_path / "half.exr").stat().st_size < (tmp_path / "full.exr").stat().st_size


def test_bad_brackets_are_refused_without_writing(tmp_path, capsys):
    capture(tmp_path / "a", "flat:0.3", stops=2, iso=100, size=(32, 32))
    capture(tmp_path / "b", "flat:0.3", stops=2, iso=400, size=(32, 32), shortest=1 / 2000)
    capture(tmp_path / "c", "flat:0.3", stops=2, size=(32, 48), shortest=1 / 1000)
    capture(tmp_path / "d", "flat:1e9", stops=2, size=(32, 32))
    a = sorted((tmp_path / "a").glob("*.dng"))
    cases = {
        "ISO": [a[0], *(tmp_path / "b").glob("frame-01.dng")],
        "frame size": [a[0], *(tmp_path / "c").glob("frame-01.dng")],
        "every pixel is clipped": [tmp_path / "d"],
    }
    for message, sources in cases.items():
        with pytest.raises(InputError, match=message):
            fuse(sources, PROFILE.camera)
    damaged = tmp_path / "damaged.dng"
    damaged.write_bytes(a[1].read_bytes()[:2000])
    out = tmp_path / "out.exr"
    assert main(["fuse", str(a[0]), str(damaged), "--out", str(out), "--profile", "simulated"]) == 1
    assert "damaged.dng" in capsys.readouterr().err and not out.exists()


def test_a_longer_frame_that_is_no_brighter_keeps_the_labelled_ratio():
    """A pair whose longer frame sums to nothing (a cap left on, a frame from another scene) gives no ratio and no
    bound to refine from: the label stands, with a note."""
    from concurrent.futures import ThreadPoolExecutor

    from hdrcam.hdr.exposure_ratios import estimate_exposures

    shape = (32, 40)
    shorter, longer = np.full(shape, 100.0, np.float32), np.zeros(shape, np.float32)
    longest = np.full(shape, 3000.0, np.float32)
    unclipped = np.zeros(shape, bool)

    def strip_data(rows):
        return [shorter[rows], longer[rows], longest[rows]], [unclipped[rows]] * 3

    notes: list[str] = []
    labelled = np.array([0.001, 0.004, 0.016])
    with ThreadPoolExecutor(2) as pool:
        exposures = estimate_exposures(strip_data, [slice(0, 16), slice(16, 32)], labelled, 15000.0, 3.0, notes, pool)
    assert exposures[1] / exposures[0] == pytest.approx(4.0)
    assert "longer frame is no brighter" in notes[0] and "using the labelled ratio" in notes[0]
    shorter[:] = -1.0  # a shorter frame with no signal above black (its noise averages below it)
    longer[:] = 400.0
    notes.clear()
    with ThreadPoolExecutor(2) as pool:
        exposures = estimate_exposures(strip_data, [slice(0, 16), slice(16, 32)], labelled, 15000.0, 3.0, notes, pool)
    assert exposures[1] / exposures[0] == pytest.approx(4.0)
    assert "no signal above black; using the labelled ratio" in notes[0]  # it read "ratio 4.0000 from 1280 pixels"


@pytest.mark.parametrize("shorter_dn, note", [
    (1000.0, r"ratio 8\.0\d+ from 1280 pixels \(the frames' sums: too little contrast for a slope"),
    (3.0, r"too little contrast for a slope \(standard error unbounded over 1280 pixels\) and signal for the sums "
          r"\(mean [23]\.\d+ DN: a DN of black-level error moves them 3\d %\); using the labelled ratio 4\.0000"),
])
def test_a_flat_field_gives_the_ratio_of_sums_where_bright_and_the_label_where_dim(shorter_dn, note):
    """No contrast, no slope: the frames' sums where a DN of black error moves them 1 % at most, else the label
    (a frame 3 DN above black read a ratio of sums a third off per DN of black error)."""
    from concurrent.futures import ThreadPoolExecutor

    from hdrcam.hdr.exposure_ratios import estimate_exposures

    rng = np.random.default_rng(0)
    shape = (32, 40)
    frames = [(shorter_dn * ratio + rng.normal(0, 2.0, shape)).astype(np.float32) for ratio in (1, 8, 64)]
    unclipped = np.zeros(shape, bool)

    def strip_data(rows):
        return [frame[rows] for frame in frames], [unclipped[rows]] * 3

    notes: list[str] = []
    labelled = np.array([0.001, 0.004, 0.016])  # a stop off the data: which was used shows
    with ThreadPoolExecutor(2) as pool, warnings.catch_warnings(record=True) as warned:
        warnings.simplefilter("always")
        exposures = estimate_exposures(strip_data, [slice(0, 16), slice(16, 32)], labelled, 1e6, 2.0, notes, pool)
    assert re.search(note, notes[0]), notes[0]
    assert [str(w.message)[:11] for w in warned] == (["frames 0-1:", "frames 1-2:"] if shorter_dn > 100 else [])
    assert exposures[1] / exposures[0] == pytest.approx(8.0 if shorter_dn > 100 else 4.0, rel=2e-3)


def test_nominal_labels_are_read_as_the_shutters_true_times():
    """Frames exposed 2^-12 .. 2^-4 s (the A7's notches) and labelled 1/4000 .. 1/15 s, as cameras label them,
    merge to the radiance that made them: the labels taken as they are left it 2.4 % dark (labels only) and put
    the whole bracket's scale on their geometric mean (estimated ratios)."""
    import dataclasses

    from hdrcam.capture.notches import SHUTTER_NOTCHES, nearest_shutter
    from hdrcam.io.raw import RawFrame

    template = read_bracket([Path(__file__).parent / "data" / "bracket-96x64"])[0]
    meta, white = template.metadata, template.metadata.white_level_dn
    radiance = np.geomspace(1.0, 300.0, template.bayer_dn.size).reshape(template.bayer_dn.shape)
    first = nearest_shutter(TRUE_SHORTEST_S).index
    notches = [SHUTTER_NOTCHES[first - 3 * k] for k in range(9)]  # 1 EV apart, towards longer times
    assert [notch.label for notch in notches[:3]] == ["1/4000", "1/2000", "1/1000"]
    rng = np.random.default_rng(0)
    frames = [RawFrame(dataclasses.replace(meta, exposure_s=float(notch.nominal)),
                       np.minimum(np.round(radiance * notch.true_s * (white - 512) * meta.iso / 100 + 512
                                           + rng.normal(0, 2, radiance.shape)), white).astype(np.uint16))
              for notch in notches]
    for estimate_ratios in (False, True):
        merged = merge_bayer(frames, PROFILE.camera, estimate_ratios=estimate_ratios)
        valid = ~merged.clipped_everywhere
        assert abs(np.median(merged.rate[valid] / radiance[valid]) - 1) < 0.002, estimate_ratios
    assert merged.notes[-1].startswith("Sony labels read as the notches' true times")
    exact = [RawFrame(dataclasses.replace(frame.metadata, make="Acme", exposure_s=notch.true_s), frame.bayer_dn)
             for frame, notch in zip(frames, notches)]  # another make's file records its exact times
    merged = merge_bayer(exact, PROFILE.camera, estimate_ratios=False)
    assert abs(np.median(merged.rate[valid] / radiance[valid]) - 1) < 0.002
    nominal_elsewhere = [RawFrame(dataclasses.replace(frame.metadata, make="Acme"), frame.bayer_dn) for frame in frames]
    np.testing.assert_array_equal(merge_bayer(nominal_elsewhere, PROFILE.camera, estimate_ratios=False).exposures_s,
                                  [frame.metadata.exposure_s for frame in frames])  # taken as written


def test_a_nine_frame_bracket_merges_to_the_radiance_that_made_it():
    """Nine frames 1 EV apart (the A7's longest bracket) need a usable-frame mask wider than 8 bits (a uint8 one
    overflowed); noise-free frames made from a known radiance ramp (1 to 1024, relative units) merge back to it
    within the 14-bit quantisation, each frame used exactly where it and its neighbours are unclipped."""
    import dataclasses

    import cv2

    from hdrcam.io.raw import RawFrame

    template = read_bracket([Path(__file__).parent / "data" / "bracket-96x64"])[0]
    meta = template.metadata
    black, white = 512.0, meta.white_level_dn
    assert np.all(meta.black_level_tile() == black)
    radiance = np.geomspace(1.0, 1024.0, template.bayer_dn.size).reshape(template.bayer_dn.shape)
    exposures = [TRUE_SHORTEST_S * 2.0 ** k for k in range(9)]
    frames = []
    for exposure in exposures:
        signal_dn = radiance * exposure * (white - black) * meta.iso / 100 + black
        frames.append(RawFrame(dataclasses.replace(meta, exposure_s=exposure),
                               np.minimum(np.round(signal_dn), white).astype(np.uint16)))
    merged = merge_bayer(frames, PROFILE.camera, estimate_ratios=False)
    assert merged.usable_frames.dtype == np.uint16 and not merged.clipped_everywhere.any()
    np.testing.assert_allclose(merged.rate, radiance, rtol=2e-3)
    for k, frame in enumerate(frames):
        clipped = (frame.bayer_dn >= black + (white - black) * 0.99).astype(np.uint8)
        expected = cv2.dilate(clipped, np.ones((3, 3), np.uint8)) == 0
        np.testing.assert_array_equal((merged.usable_frames >> k) & 1 == 1, expected, err_msg=f"frame {k}")
    assert merged.usable_frames[0, 0] == 0b111111111  # radiance 1 clips in no frame
    assert merged.usable_frames[-1, -1] == 0b11  # 1024 fills frame 1 halfway


def test_more_frames_than_the_mask_holds_are_refused():
    from hdrcam.hdr import merge

    frames = read_bracket([Path(__file__).parent / "data" / "bracket-96x64"])
    with pytest.raises(InputError, match="at most"):
        merge.merge_bayer(frames * 17, PROFILE.camera, estimate_ratios=False)


@pytest.mark.parametrize("shape", [(65, 1), (1, 1)])
def test_frames_one_pixel_wide_merge(shape):
    """A strip of one pixel (a 1-pixel-wide frame of 65 rows: its last strip is 1 x 1) merges to the rate that
    made it (OpenCV once took a 1 x 1 array beside a scalar for the scalar)."""
    import dataclasses

    from hdrcam.io.raw import RawFrame

    meta = read_bracket([Path(__file__).parent / "data" / "bracket-96x64"])[0].metadata
    signal_dn = np.linspace(500, 1500, shape[0] * shape[1]).round().reshape(shape)  # no value repeats: no pile-up
    frames = [RawFrame(dataclasses.replace(meta, exposure_s=TRUE_SHORTEST_S * 4 ** k),
                       (512 + signal_dn * 4 ** k).astype(np.uint16)) for k in range(2)]
    merged = merge_bayer(frames, PROFILE.camera, estimate_ratios=False)
    expected = signal_dn / TRUE_SHORTEST_S / (meta.white_level_dn - 512)  # relative units at ISO 100
    np.testing.assert_allclose(merged.rate, expected, rtol=1e-5)


def test_a_bracket_too_large_for_the_memory_together_is_refused_before_decoding(monkeypatch):
    """Each frame alone fits, all of them held until the merge (and what the merge makes) do not."""
    import hdrcam.limits as limits
    from hdrcam.errors import TooLargeError
    from hdrcam.hdr.bracket_input import FRAME_BYTES_PER_PIXEL, MERGED_BYTES_PER_PIXEL
    from hdrcam.io.raw import RAW_BYTES_PER_PIXEL

    bracket = Path(__file__).parent / "data" / "bracket-96x64"
    pixels = 96 * 64
    together = (FRAME_BYTES_PER_PIXEL * 4 + MERGED_BYTES_PER_PIXEL) * pixels
    assert RAW_BYTES_PER_PIXEL * pixels < 0.9 * together
    monkeypatch.setattr(limits, "available_memory_bytes", lambda: 0.9 * together)
    with pytest.raises(TooLargeError, match="4 frames .* fuse fewer frames"):
        read_bracket([bracket])
    monkeypatch.setattr(limits, "available_memory_bytes", lambda: 1.1 * together)
    assert len(read_bracket([bracket])) == 4


def test_a_white_level_of_65535_that_nothing_confirms_is_warned_about():
    """A DNG declaring the 16-bit default white level over 14-bit data: with no frame clipping the radiance scale
    would be 4x off unnoticed; a frame that clips (a pile-up at 16383) confirms the sensor's white instead."""
    import dataclasses
    import warnings

    from hdrcam.io.raw import RawFrame

    meta = read_bracket([Path(__file__).parent / "data" / "bracket-96x64"])[0].metadata
    meta = dataclasses.replace(meta, white_level_dn=65535.0)
    ramp = np.linspace(100, 3000, 96 * 64).reshape(64, 96)
    frames = [RawFrame(dataclasses.replace(meta, exposure_s=meta.exposure_s * 2 ** k),
                       np.minimum(512 + ramp * 2 ** k, 16383).astype(np.uint16)) for k in range(3)]
    with pytest.warns(UserWarning, match="no frame clips.*white level 65535"):
        merge_bayer(frames, PROFILE.camera, estimate_ratios=False)
    longer = frames + [RawFrame(dataclasses.replace(meta, exposure_s=meta.exposure_s * 8),
                                np.minimum(512 + ramp * 8, 16383).astype(np.uint16))]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        merged = merge_bayer(longer, PROFILE.camera, estimate_ratios=False)
    assert merged.clip_level_dn == 16383 - 512


@pytest.mark.parametrize("sensor_white_dn", [16383, 4095])
def test_a_white_level_of_65535_over_a_sensor_whose_green_alone_clips_scales_by_the_sensors_white(sensor_white_dn):
    """14- or 12-bit data declared with the DNG default white level 65535: green clips at the sensor's white in
    the longest frame, red and blue (0.45 and 0.4 of green) never do. Their clip levels stayed at 65535, which
    set the full well, and every radiance came out 4x (12-bit: 16x) too dark, without a warning; green's pile-up
    is the sensor's white for every position. Noise-free frames of a known radiance ramp (relative units)."""
    import dataclasses
    import warnings

    from hdrcam.io.raw import RawFrame

    meta = read_bracket([Path(__file__).parent / "data" / "bracket-96x64"])[0].metadata
    black = 512.0 if sensor_white_dn == 16383 else 128.0
    meta = dataclasses.replace(meta, black_level_dn=(black,) * 4, white_level_dn=65535.0)
    ramp = np.geomspace(0.02, 2.0, 64 * 96).reshape(64, 96)  # full wells in the longest frame (green)
    radiance = ramp * np.tile([[0.45, 1.0], [1.0, 0.4]], (32, 48))  # relative units; the longest frame is 1 s
    frames = [RawFrame(dataclasses.replace(meta, exposure_s=exposure),
                       np.minimum(np.round(radiance * exposure * (sensor_white_dn - black) + black),
                                  sensor_white_dn).astype(np.uint16)) for exposure in (1 / 16, 1 / 4, 1.0)]
    assert frames[-1].bayer_dn[0::2, 0::2].max() < sensor_white_dn  # red never clips
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        merged = merge_bayer(frames, PROFILE.camera, estimate_ratios=False)
    valid = radiance > 0.05  # well above the rounding of every frame
    np.testing.assert_allclose(merged.rate[valid], radiance[valid], rtol=5e-3)
    assert np.all(merged.clip_level_tile_dn == sensor_white_dn)


def test_clip_levels_on_both_sides_of_the_searched_range_are_warned_about():
    """Red piling up at 40 000 DN, in the top half of 512..65535, green at 16 383, far below it (blue, with no
    pile-up, takes green's): one of them is not the sensor's white, and the scale may be 2.5x off."""
    import dataclasses

    from hdrcam.io.raw import RawFrame

    meta = read_bracket([Path(__file__).parent / "data" / "bracket-96x64"])[0].metadata
    meta = dataclasses.replace(meta, white_level_dn=65535.0)
    bayer = np.linspace(600, 50000, 64 * 96).reshape(64, 96)
    bayer[0::2, 1::2] = np.minimum(bayer[0::2, 1::2], 16383)
    bayer[1::2, 0::2] = np.minimum(bayer[1::2, 0::2], 16383)
    bayer[1::2, 1::2] *= 0.2  # blue: no pile-up, so green's level
    frame = RawFrame(meta, np.minimum(bayer, 40000).astype(np.uint16))
    assert frame.clip_level_tile_dn.tolist() == [[40000, 16383], [16383, 65535]]  # per frame: as measured
    with pytest.warns(UserWarning, match=r"clip levels \(40000, 16383, 16383, 16383 DN\) lie both below and above"):
        merged = merge_bayer([frame], PROFILE.camera, estimate_ratios=False)
    assert merged.clip_level_tile_dn.tolist() == [[40000, 16383], [16383, 16383]]


def test_a_position_clipping_a_few_dn_above_the_others_shares_their_sensor_white():
    """14-bit data under the DNG default white 65535: green and blue pile up at 16372, red's ADC clips at 16383
    with 4 clipped samples in the longest frame (too few for its own pile-up). Red was left at 65535 because its
    brightest sample lay above 16372 by 11 DN: the full well 65535, every radiance 4x too dark."""
    import dataclasses

    from hdrcam.io.raw import RawFrame

    meta = read_bracket([Path(__file__).parent / "data" / "bracket-96x64"])[0].metadata
    meta = dataclasses.replace(meta, black_level_dn=(512.0,) * 4, white_level_dn=65535.0)
    radiance = np.geomspace(0.02, 2.0, 64 * 96).reshape(64, 96) * np.tile([[0.5, 1.0], [1.0, 0.3]], (32, 48))
    radiance[0, 0:8:2] = 50.0  # four red samples of a small red light
    clip = np.tile([[16383, 16372], [16372, 16372]], (32, 48))
    frames = [RawFrame(dataclasses.replace(meta, exposure_s=exposure), np.minimum(
        np.round(radiance * exposure * (16383 - 512) + 512), clip).astype(np.uint16))
        for exposure in (1 / 16, 1 / 4, 1.0)]
    merged = merge_bayer(frames, PROFILE.camera, estimate_ratios=False)
    assert merged.clip_level_tile_dn.tolist() == [[16372, 16372], [16372, 16372]]
    valid = (radiance > 0.05) & (radiance * (16383 - 512) < 16383 - 512 - 300)
    np.testing.assert_allclose(np.median(merged.rate[valid] / radiance[valid]), 1.0, rtol=5e-3)


def test_a_false_pile_up_in_one_position_leaves_the_others_at_the_white_level():
    """A stuck readout of 40 red samples at 3000 DN in every frame of a 14-bit bracket (white 16383) reads as red's
    pile-up in the shortest frame, where red stays below it. Green and blue, whose samples go far above 3000,
    were given it too (per frame, when it was their shortest frame's level): the bracket's clip levels all 3000,
    the full well 3000 DN, every radiance 6.4x too bright. They keep the white level; the scale stays right."""
    import dataclasses

    from hdrcam.io.raw import RawFrame

    meta = read_bracket([Path(__file__).parent / "data" / "bracket-96x64"])[0].metadata
    meta = dataclasses.replace(meta, black_level_dn=(512.0,) * 4, white_level_dn=16383.0)
    ramp = np.geomspace(0.02, 2.0, 64 * 96).reshape(64, 96)
    radiance = ramp * np.tile([[0.45, 1.0], [1.0, 0.4]], (32, 48))  # full wells per second
    frames = []
    for exposure in (1 / 16, 1 / 4, 1.0):
        bayer = np.minimum(np.round(radiance * exposure * (16383 - 512) + 512), 16383).astype(np.uint16)
        bayer[2:42:2, 20] = 3000  # the stuck red samples
        frames.append(RawFrame(dataclasses.replace(meta, exposure_s=exposure), bayer))
    assert frames[0].clip_level_tile_dn[0, 0] == 3000
    with pytest.warns(UserWarning, match="lie both below and above"):
        merged = merge_bayer(frames, PROFILE.camera, estimate_ratios=False)
    assert merged.clip_level_tile_dn[1].tolist() == [16383, 16383]
    valid = (radiance > 0.05) & (radiance * (16383 - 512) < 16383 - 512 - 300)  # unclipped in the shortest frame
    valid[2:42:2, 20] = False
    np.testing.assert_allclose(np.median(merged.rate[valid] / radiance[valid]), 1.0, rtol=5e-3)


def test_lights_given_as_their_own_darks_are_refused_and_darks_that_recorded_light_are_warned_about(tmp_path):
    import shutil

    for name, scene in (("lights", "flat:0.3"), ("other", "flat:30")):  # folders of RAW files (a manifest
        capture(tmp_path / f"{name}-bracket", scene, stops=2, size=(32, 32))  # would say 'light')
        (tmp_path / name).mkdir()
        for frame in (tmp_path / f"{name}-bracket").glob("*.dng"):
            shutil.copy(frame, tmp_path / name / frame.name)
    with pytest.raises(InputError, match="holds the same data as that light frame"):
        fuse([tmp_path / "lights"], PROFILE.camera, darks=tmp_path / "lights")  # was a black image, exit 0
    with pytest.warns(UserWarning, match="a dark frame, recorded light"):  # a shot of a brighter scene
        fuse([tmp_path / "lights"], PROFILE.camera, darks=tmp_path / "other")


def test_a_uniform_instrument_gives_the_sums_without_a_numpy_warning():
    """A uniform third frame: its spread, a difference of two equal sums, came out -1e-9 by rounding, and its
    square root put numpy's "invalid value" warning on stderr (calibrate of a bracket with a uniform background)."""
    from hdrcam.hdr.exposure_ratios import _ratio

    count, shorter_dn, ratio, instrument_dn = 1000.0, 300.0, 8.0, 1000.1
    shorter, instrument = count * shorter_dn, count * instrument_dn
    totals = np.array([count, shorter, ratio * shorter, instrument, instrument * shorter_dn + 1.0, instrument * ratio *
                       shorter_dn, instrument * instrument / count - 1e-6, count * shorter_dn ** 2 * 1.01,
                       count * (ratio * shorter_dn) ** 2 * 1.01, count * ratio * shorter_dn ** 2 * 1.01])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        estimate, how, _ = _ratio(totals)
    assert how == "sums" and estimate == pytest.approx(ratio)


def test_another_makes_labels_are_said_to_be_taken_as_written(tmp_path):
    """Only Sony's nominal labels are read as true times; for other makes the notes said nothing of what set the
    scale (a Canon bracket of nominal labels fused 3.9 % dark, as documented, with no word)."""
    import dataclasses

    capture(tmp_path, seed=1)
    frames = [dataclasses.replace(frame, metadata=dataclasses.replace(frame.metadata, make="Canon"))
              for frame in read_bracket([tmp_path])]
    notes = merge_bayer(frames, PROFILE.camera).notes
    assert notes[-1].startswith("Canon's labels taken as written (exact times or the notches' nominal labels")
    assert not any("taken as written" in note for note in merge_bayer(read_bracket([tmp_path]), PROFILE.camera).notes)


def test_frames_of_one_name_from_two_folders_with_one_exposure_are_told_apart_by_their_paths(tmp_path):
    """Two brackets' frame-00.dng given together were named 'frame-00.dng 0.00025 s, frame-00.dng 0.00025 s'."""
    capture(tmp_path / "a", stops=2)
    capture(tmp_path / "b", stops=2, seed=1)  # another scene: not a copy
    with pytest.raises(InputError, match="same exposure time") as refusal:
        read_bracket([tmp_path / "a" / "frame-00.dng", tmp_path / "a" / "frame-01.dng",
                      tmp_path / "b" / "frame-00.dng"])
    message = str(refusal.value)
    assert str(tmp_path / "a" / "frame-00.dng") in message and str(tmp_path / "b" / "frame-00.dng") in message
    assert "frame-01.dng" in message and str(tmp_path / "a" / "frame-01.dng") not in message
