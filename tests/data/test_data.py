"""Exposure scaling, crops, augmentation, the procedural generator and HDR folders."""

from pathlib import Path

import numpy as np
import OpenEXR
import pytest

from hdrcam.data.crops import rotate_flip, saturated_crop
from hdrcam.data.hdr_folder import HdrFolder, read_hdr_image
from hdrcam.data.night_scene import night_scene
from hdrcam.data.saturation import clipped_fraction, scale_to_clipped_fraction
from hdrcam.data.scenes import SceneSource
from hdrcam.errors import InputError

SHARED_HDR = Path(__file__).resolve().parents[3] / "shared" / "data" / "hdr"
DAMAGED = Path(__file__).resolve().parents[3] / "shared" / "data" / "damaged-exr"


@pytest.mark.parametrize("fraction", [0.01, 0.015, 0.03])
def test_scaling_leaves_exactly_the_asked_fraction_above_one(fraction):
    image = np.random.default_rng(0).lognormal(0.0, 2.0, (200, 300, 3)).astype(np.float32)
    scaled = scale_to_clipped_fraction(image, fraction)
    assert clipped_fraction(scaled) == pytest.approx(fraction, abs=1 / (200 * 300))
    assert scaled.max() <= 256.0 and scaled.min() >= 0.0


def test_scaling_clips_at_two_to_the_eight_and_refuses_black_images():
    image = np.ones((10, 10, 3), np.float32)
    image[0, 0] = 1e9  # 1e9 : 1 contrast
    image[0, 1] = 2.0
    assert scale_to_clipped_fraction(image, 0.015).max() == 256.0
    with pytest.raises(InputError, match="no light"):
        scale_to_clipped_fraction(np.zeros((8, 8, 3), np.float32), 0.015)


def test_saturated_crop_is_centred_on_bright_pixels():
    image = np.zeros((300, 300, 3), np.float32)
    image[250:256, 40:46] = 100.0
    rng = np.random.default_rng(1)
    for _ in range(20):
        assert saturated_crop(image, 64, rng, preference=1.0).max() == 100.0
    small = saturated_crop(image[:50, :50], 64, rng)  # smaller than the crop: padded
    assert small.shape == (64, 64, 3)


def test_rotate_flip_keeps_the_pixels():
    image = np.arange(4 * 6 * 3, dtype=np.float32).reshape(4, 6, 3)
    rng = np.random.default_rng(3)
    shapes = set()
    for _ in range(16):
        turned = rotate_flip(image, rng)
        shapes.add(turned.shape)
        assert np.array_equal(np.sort(turned.ravel()), np.sort(image.ravel()))
    assert shapes == {(4, 6, 3), (6, 4, 3)}


def test_night_scenes_are_seeded_and_reach_two_to_the_eight():
    first, again, other = night_scene(256, 256, seed=5, sources=30), night_scene(256, 256, seed=5, sources=30), \
        night_scene(256, 256, seed=6, sources=30)
    assert np.array_equal(first, again) and not np.array_equal(first, other)
    assert first.max() > 16.0 and np.percentile(first, 50) < 0.5 and first.min() >= 0.0


def test_procedural_source_scales_its_test_scenes_to_one_and_a_half_percent():
    source = SceneSource("procedural")
    scenes = list(source.test_scenes(64, 8, 3))
    assert [scene.name for scene in scenes] == ["night-000", "night-001", "night-002"]
    for _, scene, _ in scenes:
        assert scene.shape == (80, 80, 3)
        assert clipped_fraction(scene[8:-8, 8:-8]) == pytest.approx(0.015, abs=1.5 / 64 ** 2)
    assert np.array_equal(scenes[0].radiance, next(source.test_scenes(64, 8, 1)).radiance)  # fixed test set
    training = source.training_scene(64, 8, np.random.default_rng(0))
    assert 0.01 - 1 / 64 ** 2 <= clipped_fraction(training[8:-8, 8:-8]) <= 0.03 + 1 / 64 ** 2


@pytest.mark.skipif(not SHARED_HDR.is_dir(), reason="../shared/data/hdr not present")
def test_hdr_folder_reads_the_shared_openexr_images():
    folder = HdrFolder(SHARED_HDR)
    assert len(folder) >= 5 and all(image.min() >= 0.0 and image.ndim == 3 for image in folder.images)
    scenes = list(SceneSource(SHARED_HDR).test_scenes(128, 16, 0))
    assert len(scenes) == len(folder)


def test_hdr_folder_errors(tmp_path):
    with pytest.raises(InputError, match="not a folder"):
        HdrFolder(tmp_path / "missing")
    with pytest.raises(InputError, match="no .exr or .hdr"):
        HdrFolder(tmp_path)
    bad = np.ones((4, 4, 3), np.float32)
    bad[1, 1, 0] = np.nan
    OpenEXR.File({"type": OpenEXR.scanlineimage}, {"RGB": bad}).write(str(tmp_path / "nan.exr"))
    with pytest.raises(InputError, match="NaN or Inf"):
        read_hdr_image(tmp_path / "nan.exr")
    (tmp_path / "broken.hdr").write_bytes(b"#?RADIANCE\nnot really")
    with pytest.raises(InputError, match="Radiance"):
        read_hdr_image(tmp_path / "broken.hdr")


@pytest.mark.skipif(not DAMAGED.is_dir(), reason="../shared/data/damaged-exr not present")
def test_damaged_exr_in_a_dataset_is_a_clear_error(tmp_path):
    damaged = next(p for p in sorted(DAMAGED.iterdir()) if p.name.startswith("asan"))
    (tmp_path / "damaged.exr").write_bytes(damaged.read_bytes())
    with pytest.raises(InputError):
        HdrFolder(tmp_path)


def test_radiance_hdr_files_are_read(tmp_path):
    import cv2

    image = np.random.default_rng(0).uniform(0.01, 50.0, (8, 8, 3)).astype(np.float32)
    cv2.imwrite(str(tmp_path / "a.hdr"), cv2.cvtColor(image, cv2.COLOR_RGB2BGR))
    read = read_hdr_image(tmp_path / "a.hdr")
    # RGBE shares one exponent per pixel: 8-bit mantissas relative to the brightest channel
    assert np.all(np.abs(read - image) <= image.max(axis=-1, keepdims=True) / 128)


def _write_exr(path: Path, rgb: np.ndarray) -> None:
    OpenEXR.File({"type": OpenEXR.scanlineimage}, {"RGB": rgb.astype(np.float32)}).write(str(path))


def test_a_mixture_draws_each_source_in_proportion_to_its_weight(tmp_path):
    """Two folders whose photographs differ in colour (red or blue lamps on grey): over 1200 training draws of
    a 2:1 mixture the red share is 2/3 within 4 standard deviations of a binomial count."""
    for name, channel in (("red", 0), ("blue", 2)):
        (tmp_path / name).mkdir()
        image = np.full((64, 64, 3), 0.1, np.float32)
        rows, columns = np.mgrid[0:64, 0:64]
        image[..., channel] += 50.0 * np.exp(-((rows - 25) ** 2 + (columns - 25) ** 2) / 18.0)  # no plateau
        _write_exr(tmp_path / name / "lamp.exr", image)
    source = SceneSource(f"{tmp_path / 'red'}:2,{tmp_path / 'blue'}:1")
    rng = np.random.default_rng(0)
    draws = 1200
    red = 0
    for _ in range(draws):
        scene = source.training_scene(32, 0, rng)
        red += int(scene[..., 0].max() > scene[..., 2].max())
    expected, deviation = draws * 2 / 3, np.sqrt(draws * 2 / 3 * 1 / 3)
    assert abs(red - expected) < 4 * deviation, (red, expected)


@pytest.mark.parametrize("specification, message", [("procedural:0", "positive"), ("procedural:-1", "positive"),
                                                    ("", "SOURCE")])
def test_a_mixture_with_a_bad_weight_is_refused(specification, message):
    with pytest.raises(InputError, match=message):
        SceneSource(specification)


def test_a_mixture_takes_procedural_scenes_and_its_test_set_from_the_first_source(tmp_path):
    _write_exr(tmp_path / "a.exr", np.full((48, 48, 3), 2.0, np.float32) * np.linspace(0.01, 1, 48)[:, None, None])
    source = SceneSource(f"procedural:1,{tmp_path}:1")
    assert source.folder is None and len(source.folders) == 2
    assert [scene.name for scene in source.test_scenes(32, 0, 2)] == ["night-000", "night-001"]


def test_white_balance_jitter_keeps_green_and_stays_within_its_range():
    from hdrcam.data.augment import WB_JITTER_STOPS, white_balance_jitter

    rng = np.random.default_rng(1)
    ones = np.ones((2, 2, 3), np.float32)
    gains = np.array([white_balance_jitter(ones, rng)[0, 0] for _ in range(400)])
    np.testing.assert_allclose(gains[:, 1], 1.0, rtol=1e-6)
    stops = np.log2(gains[:, [0, 2]])
    assert np.abs(stops).max() <= 2 * WB_JITTER_STOPS + 1e-6  # each channel's +-0.25 stop, relative to green's
    assert np.abs(stops).max() > 1.5 * WB_JITTER_STOPS  # and it does reach across that range
    assert abs(float(np.mean(stops))) < 0.05  # no colour cast on average


def test_panoramas_are_cropped_from_their_middle_rows_and_other_images_are_not():
    from hdrcam.data.augment import undistorted_rows

    panorama = np.arange(100 * 200, dtype=np.float32).reshape(100, 200, 1)
    middle = undistorted_rows(panorama, 20)
    np.testing.assert_array_equal(middle, panorama[25:75])
    np.testing.assert_array_equal(undistorted_rows(panorama, 80), panorama[10:90])  # a crop needs 80 rows
    photograph = np.zeros((100, 150, 1), np.float32)
    assert undistorted_rows(photograph, 20) is photograph


def test_a_luminance_only_exr_is_read_as_grey(tmp_path):
    luminance = np.random.default_rng(2).uniform(0.1, 20.0, (6, 5)).astype(np.float32)
    OpenEXR.File({"type": OpenEXR.scanlineimage}, {"Y": luminance}).write(str(tmp_path / "y.exr"))
    image = read_hdr_image(tmp_path / "y.exr")
    assert image.shape == (6, 5, 3)
    for channel in range(3):
        np.testing.assert_array_equal(image[..., channel], luminance)


def test_test_scenes_of_files_sharing_a_stem_keep_distinct_names(tmp_path):
    import cv2

    image = np.random.default_rng(1).uniform(0.01, 4.0, (64, 64, 3)).astype(np.float32)
    _write_exr(tmp_path / "sun.exr", image)
    cv2.imwrite(str(tmp_path / "sun.hdr"), cv2.cvtColor(image, cv2.COLOR_RGB2BGR))
    _write_exr(tmp_path / "moon.exr", image)
    names = [scene.name for scene in SceneSource(str(tmp_path)).test_scenes(32, 0, 0)]
    assert names == ["moon", "sun.exr", "sun.hdr"]
    cv2.imwrite(str(tmp_path / "sun.exr.hdr"), cv2.cvtColor(image, cv2.COLOR_RGB2BGR))  # its stem: sun.exr's name
    names = [scene.name for scene in SceneSource(str(tmp_path)).test_scenes(32, 0, 0)]
    assert names == ["moon", "sun.exr", "sun.exr.hdr", "sun.hdr"]


def test_a_training_photograph_without_light_is_refused_by_name_before_training(tmp_path):
    _write_exr(tmp_path / "lamp.exr", np.full((64, 64, 3), 2.0, np.float32) * np.linspace(0.01, 1, 64)[:, None, None])
    _write_exr(tmp_path / "lens-cap.exr", np.zeros((64, 64, 3), np.float32))
    with pytest.raises(InputError, match=r"lens-cap\.exr: the photograph holds no light"):
        SceneSource(f"procedural:1,{tmp_path}:1").check_training_folders()


def test_dark_crops_are_drawn_again_and_a_photograph_that_is_always_dark_is_named(tmp_path):
    half_dark = np.zeros((256, 256, 3), np.float32)
    half_dark[:, :128] = np.random.default_rng(0).uniform(0.1, 4.0, (256, 128, 3))
    (tmp_path / "half").mkdir()
    _write_exr(tmp_path / "half" / "dusk.exr", half_dark)
    source = SceneSource(tmp_path / "half")
    for seed in range(24):  # crops drawn anywhere (one in five) land in the black half at times
        scene = source.training_scene(48, 0, np.random.default_rng(seed))
        assert 0.009 <= clipped_fraction(scene) <= 0.031  # 1-3 %, to within a pixel of 48^2
    star = np.zeros((256, 256, 3), np.float32)
    star[100:102, 100:102] = 50.0  # 4 lit pixels: no 48 px crop has 1 % of its pixels lit
    (tmp_path / "stars").mkdir()
    _write_exr(tmp_path / "stars" / "star.exr", star)
    with pytest.raises(InputError, match=r"star\.exr: 16 training crops .*\(too little light"):
        SceneSource(tmp_path / "stars").training_scene(48, 0, np.random.default_rng(0))


def test_a_photograph_near_the_float32_limit_trains_finite_scenes(tmp_path):
    image = np.broadcast_to(np.linspace(1e37, 3.3e38, 64 * 64, dtype=np.float32).reshape(64, 64, 1), (64, 64, 3))
    _write_exr(tmp_path / "huge.exr", image)
    scene = SceneSource(tmp_path).training_scene(32, 8, np.random.default_rng(0))
    assert np.isfinite(scene).all() and 0.009 <= clipped_fraction(scene[8:-8, 8:-8]) <= 0.031


def test_a_shortfall_names_a_fraction_under_one_pixel_apart_from_a_plateau():
    from hdrcam.data.saturation import fraction_shortfall

    assert fraction_shortfall(0.016, 0.015, 100) is None
    assert "1.5 % of 15 pixels is less than one" in fraction_shortfall(0.0, 0.015, 15)  # it said: a plateau
    assert "a plateau at its brightest" in fraction_shortfall(0.2, 0.015, 10_000)


def test_a_value_near_float32s_top_is_clipped_without_an_overflow_warning():
    """3e38 over a scale below 1 overflowed to inf with numpy's RuntimeWarning on stderr (the result was right)."""
    import warnings

    from hdrcam.data.saturation import HIGHLIGHT_PEAK, scale_to_clipped_fraction

    radiance = np.full((40, 40, 3), 0.01, np.float32)
    radiance[:5] = 0.5
    radiance[0, 0] = 3e38
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        scaled = scale_to_clipped_fraction(radiance, 0.1)
    assert scaled[0, 0].tolist() == [HIGHLIGHT_PEAK] * 3 and np.isfinite(scaled).all()


def _lamps(tmp_path, height=400, width=600):
    """Photographs whose brightest 1.5 % are four lamps (1.6 % of the pixels) on dim texture."""
    rng = np.random.default_rng(0)
    half = max(2, int(np.sqrt(0.004 * height * width)) // 2)
    for index in range(6):
        image = rng.uniform(0.01, 0.05, (height, width, 3)).astype(np.float32)
        for _ in range(4):
            y, x = rng.integers(half, height - half), rng.integers(half, width - half)
            image[y - half:y + half + 1, x - half:x + half + 1] = 50.0
        OpenEXR.File({"type": OpenEXR.scanlineimage}, {"RGB": image}).write(str(tmp_path / f"p{index}.exr"))
    return tmp_path


@pytest.mark.parametrize("data", ["procedural", "lamps"])
def test_a_test_scenes_scored_centre_holds_a_highlight_and_does_not_depend_on_the_margin(tmp_path, data):
    """The crop of size + 2 margin put its bright pixel anywhere in it: a lamp could sit in the margin only, the
    scored centre then pushing dim texture over 1; and a PSF of another size scored other regions under the same
    names."""
    source = SceneSource("procedural" if data == "procedural" else str(_lamps(tmp_path)))
    size = 96
    centres = {}
    for margin in (8, 31, 127):
        scenes = list(source.test_scenes(size, margin, 4))
        centres[margin] = [scene.radiance[margin:margin + size, margin:margin + size] for scene in scenes]
        for (name, scene, _), centre in zip(scenes, centres[margin]):
            assert scene.shape == (size + 2 * margin, size + 2 * margin, 3)
            if data == "lamps":  # a lamp in the scored centre: 1000 times the texture
                assert centre.max() > 100 * np.median(centre), (name, margin)
    for margin in (31, 127):  # the scored region, before scaling, is the same: so is its scaled value here
        for first, other in zip(centres[8], centres[margin]):
            np.testing.assert_allclose(other / other.max(), first / first.max(), rtol=1e-5)


def test_a_mixture_led_by_procedural_tests_on_procedural_scenes_only(tmp_path):
    """A mixture's test set comes from its first source: procedural,DIR drew among both sources (a photograph
    scored as night-003) and shifted every scene's random stream."""
    mixture = SceneSource(f"procedural:0.5,{_lamps(tmp_path)}:0.5").test_scenes(64, 8, 4)
    alone = SceneSource("procedural").test_scenes(64, 8, 4)
    assert [scene.name for scene in mixture] == [scene.name for scene in alone]
    for first, second in zip(mixture, alone):
        np.testing.assert_array_equal(first.radiance, second.radiance)


def test_a_photograph_smaller_than_the_test_crop_is_warned_about_where_it_can_be_scored(tmp_path):
    """One that cannot be scored was also said to be 'scored too', and then evaluate said 'not scored'."""
    from hdrcam.data.scenes import protocol_shortfall

    _lamps(tmp_path, height=80, width=120)
    with pytest.warns(UserWarning, match=r"120 x 80 px, smaller than the 96 px test crop: mirrored") as caught:
        scenes = list(SceneSource(str(tmp_path)).test_scenes(96, 8, 0))
    warned = {Path(str(warning.message).split(":")[0]).stem for warning in caught}
    scoreable = {scene.name for scene in scenes if protocol_shortfall(scene.radiance[8:104, 8:104]) is None}
    assert warned == scoreable and 0 < len(scoreable) < len(scenes), (warned, scoreable)


def test_a_point_of_light_on_black_is_refused_with_how_many_pixels_hold_light():
    """A single lit pixel asked to leave 1.5 % of the pixels above white: the quantile is 0 and the error said
    the image had no light."""
    from hdrcam.data.saturation import saturation_scale
    from hdrcam.errors import InputError

    scene = np.zeros((100, 100, 3), np.float32)
    scene[50, 50] = 1e9
    with pytest.raises(InputError, match=r"only 1 of 10000 pixels hold light \(0.01 %\), fewer than the 1.5 % asked"):
        saturation_scale(scene, 0.015)
    assert saturation_scale(scene, 5e-5) == pytest.approx(1e9)
    with pytest.raises(InputError, match="every pixel is zero"):
        saturation_scale(np.zeros((4, 4, 3), np.float32), 0.015)


def test_hidden_files_and_folders_named_like_photographs_are_not_training_photographs(tmp_path):
    """A macOS resource fork (._a.exr, beside a photograph copied from a Mac) stopped training with 'not a
    readable OpenEXR file'; a folder named x.exr was reported as 'no such file'."""
    from hdrcam.data.hdr_folder import hdr_files

    _write_exr(tmp_path / "a.exr", np.ones((8, 8, 3), np.float32))
    (tmp_path / "._a.exr").write_bytes(b"\x00\x05\x16\x07" + bytes(60))  # AppleDouble header
    (tmp_path / "x.exr").mkdir()
    assert hdr_files(tmp_path) == [tmp_path / "a.exr"]
    (tmp_path / "b.exr").symlink_to(tmp_path / "gone.exr")  # kept: reading it names it, no photograph goes missing
    assert hdr_files(tmp_path) == [tmp_path / "a.exr", tmp_path / "b.exr"]


def test_training_crops_of_a_photograph_clipped_at_source_still_exceed_white_as_asked(tmp_path):
    """A lamp whose pixels share one value (clipped in every frame of its bracket) holding more of a crop than the
    fraction asked: scaled by the quantile, it landed on 1 exactly and the crop held nothing above 1, teaching
    that clipped pixels are white (a real photograph with its brightest 3 % clipped: 0.35 % above 1 on average,
    0 at least); a photograph that is one plateau could never be saturated, and trained silently."""
    from hdrcam.data.saturation import TRAIN_CLIPPED_RANGE, clipped_fraction

    rng = np.random.default_rng(0)
    photograph = rng.lognormal(0.0, 1.0, (256, 256, 1)).astype(np.float32) * np.ones(3, np.float32)
    rows, columns = np.mgrid[0:256, 0:256]
    photograph[(rows - 60) ** 2 + (columns - 60) ** 2 <= 5 ** 2] = 1e3  # a lamp clipped: 2 % of a 64 px crop
    (tmp_path / "clipped").mkdir()
    _write_exr(tmp_path / "clipped" / "a.exr", photograph)
    source = SceneSource(tmp_path / "clipped")
    fractions = [clipped_fraction(source.training_scene(64, 8, np.random.default_rng(seed))[8:-8, 8:-8])
                 for seed in range(12)]
    assert min(fractions) >= TRAIN_CLIPPED_RANGE[0] / 2, fractions
    (tmp_path / "flat").mkdir()
    _write_exr(tmp_path / "flat" / "a.exr", np.full((96, 96, 3), 5.0, np.float32))
    with pytest.raises(InputError, match="a plateau at their brightest"):
        SceneSource(tmp_path / "flat").training_scene(32, 8, np.random.default_rng(0))


def test_a_folder_named_like_a_mixture_is_taken_as_itself_and_an_ambiguous_one_refused(tmp_path, monkeypatch):
    """--data data/shoot:2 trained on data/shoot with weight 2 (recorded so), and data/2024,night was refused as
    'data/2024 is not a folder'."""
    from hdrcam.data.scenes import parse_mixture

    monkeypatch.chdir(tmp_path)
    for name in ("shoot:2", "2024,night"):
        (tmp_path / name).mkdir()
        assert parse_mixture(name) == [(name, 1.0)]
    assert parse_mixture("shoot:2,procedural:3") == [("shoot:2", 1.0), ("procedural", 3.0)]
    (tmp_path / "shoot").mkdir()
    with pytest.raises(InputError, match="shoot:2 is a folder, and shoot with weight 2 too"):
        parse_mixture("shoot:2,procedural")
    assert parse_mixture("procedural") == [("procedural", 1.0)]


def test_a_training_photograph_smaller_than_a_training_scene_is_named_once_before_training(tmp_path):
    """Evaluate warned of a photograph smaller than its crop (mirrored to fill it); training mirrored it silently."""
    _write_exr(tmp_path / "thumbnail.exr", np.linspace(0.1, 5.0, 40 * 60 * 3, dtype=np.float32).reshape(40, 60, 3))
    _write_exr(tmp_path / "large.exr", np.linspace(0.1, 5.0, 128 * 128 * 3, dtype=np.float32).reshape(128, 128, 3))
    with pytest.warns(UserWarning, match=r"thumbnail\.exr: 60 x 40 px, smaller than the 96 px training") as caught:
        SceneSource(str(tmp_path)).check_training_folders(96)
    assert len(caught) == 1


def test_a_folder_named_like_a_mixture_of_existing_folders_is_ambiguous_alone_too(tmp_path, monkeypatch):
    """The whole --data naming a folder took it as itself even where its split reading names existing folders:
    shoot:2 beside shoot, a,b beside a and b."""
    from hdrcam.data.scenes import parse_mixture

    monkeypatch.chdir(tmp_path)
    for name in ("shoot:2", "shoot", "a,b", "a", "b"):
        (tmp_path / name).mkdir()
    for data in ("shoot:2", "a,b"):
        with pytest.raises(InputError, match="a folder of that name, and the mixture .* too"):
            parse_mixture(data)
