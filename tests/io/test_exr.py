"""EXR input and output on real files, damaged files and the extremes of the half range."""

from __future__ import annotations

import os

import numpy as np
import OpenEXR
import pytest

from hdrcam.errors import InputError, OutputExistsError, escaped_name
from hdrcam.io.exr import HALF_MAX, read_exr, write_exr, write_exr_channels


@pytest.mark.parametrize("name", ["Bonita", "Cannon", "Carrots", "Desk", "MtTamWest", "Flowers"])
def test_real_hdr_images_read_as_finite_linear_rgb(shared_data, name):
    rgb = read_exr(shared_data / "hdr" / f"{name}.exr").rgb()
    assert rgb.ndim == 3 and rgb.shape[2] == 3 and rgb.dtype == np.float32
    assert np.isfinite(rgb).all() and rgb.max() > 0


def test_luminance_chroma_file_converts_to_the_rgb_it_encodes(tmp_path):
    rng = np.random.default_rng(0)
    rgb = rng.uniform(0.1, 4.0, (8, 6, 3))
    weights = np.array([0.212639, 0.715169, 0.072192])  # Rec. 709 / D65 luminance (ITU-R BT.709, 6 digits)
    luminance = rgb @ weights
    channels = {"Y": luminance, "RY": (rgb[..., 0] - luminance) / luminance, "BY": (rgb[..., 2] - luminance) / luminance}
    OpenEXR.File({"type": OpenEXR.scanlineimage},
                 {k: v.astype(np.float32) for k, v in channels.items()}).write(str(tmp_path / "yc.exr"))
    np.testing.assert_allclose(read_exr(tmp_path / "yc.exr").rgb(), rgb, rtol=1e-4)


@pytest.mark.parametrize("chromaticities", [
    (0.64, 0.33, 0.30, 0.60, 0.15, 0.06, 0.3127, 0.3290),  # Rec. 709 / D65
    (0.7347, 0.2653, 0.0, 1.0, 0.0001, -0.077, 0.32168, 0.33767),  # ACES AP0
    (0.680, 0.320, 0.265, 0.690, 0.150, 0.060, 0.314, 0.351),  # DCI-P3
])
def test_luminance_weights_are_the_normalised_primary_matrixs_y_row(chromaticities):
    import warnings

    from hdrcam.io.exr import luminance_weights

    with warnings.catch_warnings():  # colour-science warns that matplotlib is absent
        warnings.simplefilter("ignore")
        import colour
    values = np.reshape(chromaticities, (4, 2))
    np.testing.assert_allclose(luminance_weights(chromaticities),
                               colour.normalised_primary_matrix(values[:3], values[3])[1], rtol=0, atol=1e-12)


def test_luminance_weights_of_primaries_on_the_axes_need_no_division_by_their_y():
    from hdrcam.io.exr import luminance_weights

    cie_xyz = (1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1 / 3, 1 / 3)  # CIE XYZ's own primaries, equal-energy white
    np.testing.assert_allclose(luminance_weights(cie_xyz), [0.0, 1.0, 0.0], atol=1e-12)


@pytest.mark.parametrize("chromaticities", [
    (0.64, 0.33, 0.30, 0.60, 0.15, 0.06, 0.3127, 0.0),  # white y = 0
    (0.2, 0.2, 0.3, 0.3, 0.4, 0.4, 0.3127, 0.3290),  # primaries on one line
])
def test_a_luminance_chroma_file_with_unusable_chromaticities_is_an_input_error(tmp_path, chromaticities):
    y = np.ones((4, 4), np.float32)
    header = {"type": OpenEXR.scanlineimage, "chromaticities": chromaticities}
    OpenEXR.File(header, {"Y": y, "RY": 0 * y, "BY": 0 * y}).write(str(tmp_path / "yc.exr"))
    with pytest.raises(InputError, match="chromaticities"):
        read_exr(tmp_path / "yc.exr")


@pytest.mark.parametrize("half", [False, True])
def test_round_trip_rgb_and_single_channel_with_attributes(tmp_path, half):
    rgb = np.random.default_rng(1).uniform(0, 300, (5, 7, 3)).astype(np.float32)
    write_exr(tmp_path / "rgb.exr", rgb, half=half, attributes={"pixel_pitch_m": 5.97e-6, "note": "bracket 3"})
    image = read_exr(tmp_path / "rgb.exr")
    np.testing.assert_allclose(image.rgb(), rgb, rtol=1e-3 if half else 0)
    assert image.attributes["note"] == "bracket 3"
    assert image.attributes["pixel_pitch_m"] == pytest.approx(5.97e-6, rel=1e-6)
    write_exr(tmp_path / "y.exr", rgb[..., 0], channel_names=("height_m",), half=half)
    np.testing.assert_allclose(read_exr(tmp_path / "y.exr").single(), rgb[..., 0], rtol=1e-3 if half else 0)


def test_a_non_utf8_name_in_an_attribute_is_stored_as_its_bytes_as_every_other_output_writes_it(tmp_path):
    """One escaping (hdrcam.errors.escaped_name) for EXR attributes and the other outputs: an undecodable byte
    was stored as Python's surrogate (caf\\udce9), where summary.md and evaluate's names write caf\\xe9."""
    source = os.fsdecode(b"/card/caf\xe9.dng")
    write_exr(tmp_path / "f.exr", np.ones((2, 2, 3), np.float32), attributes={"source": source, "note": "\ud800"})
    attributes = read_exr(tmp_path / "f.exr").attributes
    assert attributes["source"] == escaped_name(source) == "/card/caf\\xe9.dng"
    assert attributes["note"] == "\\ud800"  # not from a file name: no byte to write, and no failure


def test_half_overflow_and_non_finite_values_are_refused_without_a_file(tmp_path):
    over = np.full((4, 4, 3), 2.0 ** 17, np.float32)
    with pytest.raises(InputError, match="exceed the half-float range"):
        write_exr(tmp_path / "over.exr", over, half=True)
    write_exr(tmp_path / "edge.exr", np.full((2, 2, 3), HALF_MAX, np.float32), half=True)  # the largest half is fine
    assert np.isfinite(read_exr(tmp_path / "edge.exr").rgb()).all()
    with pytest.raises(InputError, match="NaN or Inf"):
        write_exr(tmp_path / "nan.exr", np.array([[np.nan, 1.0]], np.float32))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["edge.exr"]


def test_existing_output_is_never_replaced_unless_asked(tmp_path):
    path = write_exr(tmp_path / "a.exr", np.ones((2, 2, 3), np.float32))
    before = path.read_bytes()
    with pytest.raises(OutputExistsError, match="already exists"):
        write_exr(path, np.zeros((2, 2, 3), np.float32))
    assert path.read_bytes() == before
    write_exr(path, np.zeros((2, 2, 3), np.float32), overwrite=True)
    assert read_exr(path).rgb().max() == 0


def test_damaged_files_give_one_line_input_errors(shared_data):
    damaged = sorted(p for p in (shared_data / "damaged-exr").iterdir() if not p.name.startswith("LICENSE"))
    assert damaged
    for path in damaged:
        with pytest.raises(InputError) as caught:
            read_exr(path)
        assert "\n" not in str(caught.value) and path.name in str(caught.value)


def test_missing_file_and_missing_colour_channels(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        read_exr(tmp_path / "absent.exr")
    write_exr(tmp_path / "mono.exr", np.ones((2, 2), np.float32))
    with pytest.raises(InputError, match="not R, G, B"):
        read_exr(tmp_path / "mono.exr").rgb()


def test_uncompressed_and_zip_files_hold_the_same_planes_and_say_which_they_are(tmp_path):
    rng = np.random.default_rng(0)
    planes = {"R": rng.random((20, 30), np.float32), "clipped": (rng.random((20, 30)) > 0.9).astype(np.float32)}
    sizes = {}
    for compression, code in (("none", OpenEXR.NO_COMPRESSION), ("zip", OpenEXR.ZIP_COMPRESSION)):
        path = write_exr_channels(tmp_path / f"{compression}.exr", planes, compression=compression)
        image = read_exr(path)
        assert image.channels.keys() == planes.keys()
        for name, plane in planes.items():
            np.testing.assert_array_equal(image.channels[name], plane)
        with OpenEXR.File(str(path), header_only=True) as file:
            assert file.header()["compression"] == code
        sizes[compression] = path.stat().st_size
    assert sizes["zip"] < sizes["none"]
    with pytest.raises(ValueError, match="compression"):
        write_exr_channels(tmp_path / "x.exr", planes, compression="piz")


def test_colour_groups_and_masks_are_written_without_copies_and_read_back_exactly(tmp_path):
    """An H x W x 3 group under "RGB" becomes R, G, B (under another key K: K.R, K.G, K.B), taken straight from the
    interleaved array; a bool mask is stored as half 0 / 1 and reads back as float32."""
    rng = np.random.default_rng(2)
    rgb = rng.uniform(0, 5e4, (6, 9, 3)).astype(np.float32)
    variance = rng.uniform(0, 1e30, (6, 9, 3)).astype(np.float32)
    mask = rng.random((6, 9)) > 0.5
    path = write_exr_channels(tmp_path / "g.exr", {"RGB": rgb, "clipped": mask, "variance": variance})
    image = read_exr(path)
    assert set(image.channels) == {"R", "G", "B", "clipped", "variance.R", "variance.G", "variance.B"}
    np.testing.assert_array_equal(image.rgb(), rgb)
    np.testing.assert_array_equal(np.stack([image.channels[f"variance.{c}"] for c in "RGB"], -1), variance)
    np.testing.assert_array_equal(image.channels["clipped"], mask.astype(np.float32))
    with OpenEXR.File(str(path), separate_channels=True) as file:
        assert file.channels()["clipped"].type() == OpenEXR.HALF
    rgb[2, 3, 1] = np.nan
    with pytest.raises(InputError, match="NaN or Inf"):
        write_exr_channels(tmp_path / "nan.exr", {"RGB": rgb})
    with pytest.raises(ValueError, match="H x W x 3"):
        write_exr_channels(tmp_path / "four.exr", {"RGBA": np.zeros((2, 2, 4), np.float32)})
    assert not (tmp_path / "nan.exr").exists() and not (tmp_path / "four.exr").exists()


AP0 = (0.7347, 0.2653, 0.0, 1.0, 0.0001, -0.077, 0.32168, 0.33767)  # ACES 2065-1 primaries and white


def test_rgb_in_other_primaries_is_read_as_rec_709(tmp_path):
    """A file whose chromaticities attribute names ACES AP0 (the openexr-images Carrots.exr does) was read as if its
    numbers were Rec. 709: a pure Rec. 709 red stored in AP0 came back (0.44, 0.09, 0.02). AP0 -> Rec. 709 with
    Bradford adaptation (ACES's published matrix, to 4 digits): columns (2.5217, -0.2765, -0.0154) for AP0
    red, (-1.1341, 1.3727, -0.1530) green, (-0.3876, -0.0962, 1.1684) blue."""
    expected = np.array([[2.5217, -1.1341, -0.3876], [-0.2765, 1.3727, -0.0962], [-0.0154, -0.1530, 1.1684]])
    pixels = np.eye(3, dtype=np.float32)[None]  # AP0 red, green, blue in a 1 x 3 image
    header = {"type": OpenEXR.scanlineimage, "chromaticities": AP0}
    OpenEXR.File(header, {"RGB": pixels}).write(str(tmp_path / "ap0.exr"))
    image = read_exr(tmp_path / "ap0.exr")
    np.testing.assert_allclose(image.rgb()[0], expected.T, atol=2e-4)
    assert "chromaticities" not in image.attributes  # no longer what the pixels are in


@pytest.mark.parametrize("chromaticities", [(0.64, 0.33, 0.30, 0.60, 0.15, 0.06, 0.3127, 0.3290), (0.0,) * 8])
def test_rec_709_or_degenerate_chromaticities_leave_the_pixels_as_stored(tmp_path, chromaticities):
    pixels = np.random.default_rng(0).uniform(0, 4, (4, 5, 3)).astype(np.float32)
    OpenEXR.File({"type": OpenEXR.scanlineimage, "chromaticities": chromaticities}, {"RGB": pixels}).write(
        str(tmp_path / "file.exr"))
    np.testing.assert_array_equal(read_exr(tmp_path / "file.exr").rgb(), pixels)


def test_a_multi_part_file_is_read_from_its_colour_part(tmp_path):
    """A renderer's file with depth in part 0 and the image in part 1 was refused as 'has channels ['Z'], not R,
    G, B'."""
    rgb = np.random.default_rng(1).uniform(0, 4, (6, 8, 3)).astype(np.float32)
    header = {"type": OpenEXR.scanlineimage, "compression": OpenEXR.ZIP_COMPRESSION}
    depth = OpenEXR.Part(dict(header, name="depth"), {"Z": np.ones((6, 8), np.float32)})
    image = OpenEXR.Part(dict(header, name="beauty"), {name: np.ascontiguousarray(rgb[..., i])
                                                       for i, name in enumerate("RGB")})
    with OpenEXR.File([depth, image]) as exr:
        exr.write(str(tmp_path / "parts.exr"))
    np.testing.assert_array_equal(read_exr(tmp_path / "parts.exr").rgb(), rgb)


def test_a_multi_part_file_too_large_for_memory_is_refused_by_all_its_parts(tmp_path, monkeypatch):
    """Every part is decoded: the check read the first part's header only (a small depth part before the image)."""
    from hdrcam import limits
    from hdrcam.errors import TooLargeError

    corner = np.array([0, 0], np.int32)
    header = {"type": OpenEXR.scanlineimage, "compression": OpenEXR.ZIP_COMPRESSION,
              "displayWindow": (corner, np.array([299, 299], np.int32))}
    depth = OpenEXR.Part(dict(header, name="depth", dataWindow=(corner, np.array([3, 3], np.int32))),
                         {"Z": np.ones((4, 4), np.float32)})
    image = OpenEXR.Part(dict(header, name="beauty"), {name: np.ones((300, 300), np.float32) for name in "RGB"})
    with OpenEXR.File([depth, image]) as exr:
        exr.write(str(tmp_path / "parts.exr"))
    monkeypatch.setattr(limits, "available_memory_bytes", lambda: 1_000_000)
    with pytest.raises(TooLargeError, match=r"parts.exr: 2 parts needs about 3.24 MB"):
        read_exr(tmp_path / "parts.exr")


@pytest.mark.parametrize("chromaticities", [AP0, (0.708, 0.292, 0.170, 0.797, 0.131, 0.046, 0.3127, 0.3290),
                                            (0.680, 0.320, 0.265, 0.690, 0.150, 0.060, 0.314, 0.351)])
def test_the_primaries_matrix_is_colour_sciences(chromaticities):
    """hdrcam's own (numpy only: a GPU machine's training lacks colour-science) against colour-science's, for
    ACES AP0, Rec. 2020 and DCI-P3."""
    import warnings

    from hdrcam.colorimetry import EQUAL_ENERGY_XYZ_CHROMATICITIES, to_rec709_matrix

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        import colour
    source = colour.RGB_Colourspace("file", np.reshape(chromaticities[:6], (3, 2)), chromaticities[6:])
    rec709 = colour.RGB_COLOURSPACES["ITU-R BT.709"]
    np.testing.assert_allclose(to_rec709_matrix(chromaticities), colour.matrix_RGB_to_RGB(
        source, rec709, chromatic_adaptation_transform="Bradford"), atol=1e-12)
    adaptation = colour.adaptation.matrix_chromatic_adaptation_VonKries(
        colour.xy_to_XYZ([1 / 3, 1 / 3]), colour.xy_to_XYZ([0.3127, 0.3290]), transform="Bradford")
    np.testing.assert_allclose(to_rec709_matrix(EQUAL_ENERGY_XYZ_CHROMATICITIES), rec709.matrix_XYZ_to_RGB @ adaptation,
                               atol=1e-12)


def test_subsampled_chroma_is_reconstructed_as_openexr_does(tmp_path):
    """OpenEXR's RGBA interface interpolates the missing chroma samples with its half-band filter, which keeps a
    smooth chroma ramp exact; each sample repeated put every other pixel half a step off (luminance-chroma
    photographs 2-5 % (median) off OpenEXR's own decode)."""
    height, width = 40, 48
    y, x = np.mgrid[:height, :width].astype(np.float32)
    red_difference, blue_difference = 0.2 + 0.01 * x + 0.005 * y, -0.1 + 0.004 * x - 0.006 * y
    luminance = np.full((height, width), 2.0, np.float32)

    def subsampled(plane: np.ndarray) -> np.ndarray:  # the binding takes a full-size array, the samples first
        packed = np.zeros_like(plane)
        packed.ravel()[:plane[::2, ::2].size] = plane[::2, ::2].ravel()
        return packed

    channels = {"Y": OpenEXR.Channel("Y", luminance), "RY": OpenEXR.Channel("RY", subsampled(red_difference), 2, 2),
                "BY": OpenEXR.Channel("BY", subsampled(blue_difference), 2, 2)}
    OpenEXR.File({"type": OpenEXR.scanlineimage}, channels).write(str(tmp_path / "yc.exr"))
    rgb = read_exr(tmp_path / "yc.exr").rgb()
    inner = (slice(14, -14), slice(14, -14))  # the filter reaches 13 px; the edges: the next test
    np.testing.assert_allclose(rgb[inner][..., 0], ((red_difference + 1) * luminance)[inner], rtol=2e-5)
    np.testing.assert_allclose(rgb[inner][..., 2], ((blue_difference + 1) * luminance)[inner], rtol=2e-5)


def test_chroma_beyond_the_edges_repeats_the_first_and_last_sample_as_openexr_pads(tmp_path):
    """OpenEXR's FromYca repeats the first and last stored chroma sample beyond a row's ends (padTmpBuf) and
    clamps rows; mirroring the zero-filled grid instead dropped every weight beyond an edge (up to 78 % off
    within 13 px of the edges of Flowers.exr). Expected values from the filter's definition, sample by sample."""
    from hdrcam.io.exr import CHROMA_WEIGHTS

    height, width = 8, 36
    stored = np.cos(np.arange(width // 2, dtype=np.float32)) * 0.3  # chroma at even columns, the same every row
    red_difference = np.zeros((height, width), np.float32)
    red_difference[:, ::2] = stored

    def subsampled(plane: np.ndarray) -> np.ndarray:
        packed = np.zeros_like(plane)
        packed.ravel()[:plane[::2, ::2].size] = plane[::2, ::2].ravel()
        return packed

    luminance = np.ones((height, width), np.float32)
    OpenEXR.File({"type": OpenEXR.scanlineimage}, {
        "Y": OpenEXR.Channel("Y", luminance), "RY": OpenEXR.Channel("RY", subsampled(red_difference), 2, 2),
        "BY": OpenEXR.Channel("BY", np.zeros((height, width), np.float32), 2, 2)}).write(str(tmp_path / "yc.exr"))
    red = read_exr(tmp_path / "yc.exr").rgb()[..., 0] - 1.0  # R = (RY + 1) Y with Y = 1
    clamped = [stored[min(max(j, 0), stored.size - 1)] for j in range(-8, stored.size + 8)]  # index j + 8
    expected = [stored[x // 2] if x % 2 == 0 else sum(
        weight * (clamped[x // 2 - i + 8] + clamped[x // 2 + 1 + i + 8]) for i, weight in enumerate(CHROMA_WEIGHTS))
        for x in range(width)]
    np.testing.assert_allclose(red, np.broadcast_to(expected, red.shape), atol=2e-6)


def test_an_exr_cut_short_in_its_pixel_data_says_so(tmp_path):
    """OpenEXR's binding decodes no part of a file cut short in its pixels (an interrupted copy): read_exr said
    "no image part", as if the file held none."""
    pixels = np.random.default_rng(0).random((256, 256, 3), np.float32)
    write_exr(tmp_path / "whole.exr", pixels)
    data = (tmp_path / "whole.exr").read_bytes()
    (tmp_path / "cut.exr").write_bytes(data[:len(data) // 2])
    with pytest.raises(InputError, match=r"cut.exr: .*truncated or damaged"):
        read_exr(tmp_path / "cut.exr")


def test_a_deep_exr_is_refused_as_deep(tmp_path):
    """A deep file's channels hold a list of samples per pixel: it was refused as "unsupported pixel type object"."""
    samples = np.empty((4, 4), dtype=object)
    for row in range(4):
        for column in range(4):
            samples[row, column] = np.array([0.5, 0.25], np.float32)
    OpenEXR.File({"type": OpenEXR.deepscanline, "compression": OpenEXR.ZIPS_COMPRESSION},
                 {"A": OpenEXR.Channel(samples)}).write(str(tmp_path / "deep.exr"))
    with pytest.raises(InputError, match="deep image"):
        read_exr(tmp_path / "deep.exr")


def _box(x_min: int, y_min: int, x_max: int, y_max: int):
    return (np.array([x_min, y_min], np.int32), np.array([x_max, y_max], np.int32))


@pytest.mark.parametrize("data_window", [
    (8, 5, 19, 12),  # a crop (a renderer's bounding box), partly beyond the frame's bottom
    (-6, -4, 29, 19),  # overscan: stored pixels beyond the frame on every side
    (-3, 7, 6, 30),  # only a corner of the stored pixels lies in the frame
])
def test_the_image_is_the_display_window_whatever_the_data_window(tmp_path, data_window):
    """OpenEXR's display window is the image's frame and its data window the pixels stored; the data window was
    returned as the image (a crop came back as its bounding box, overscan as a larger image)."""
    x_min, y_min, x_max, y_max = data_window
    world = np.random.default_rng(2).uniform(0.5, 4, (50, 50, 3)).astype(np.float32)  # pixel (x, y) at [y + 10, x + 10]
    stored = world[y_min + 10:y_max + 11, x_min + 10:x_max + 11]
    header = {"type": OpenEXR.scanlineimage, "compression": OpenEXR.ZIP_COMPRESSION,
              "dataWindow": _box(*data_window), "displayWindow": _box(0, 0, 19, 9)}
    OpenEXR.File(header, {name: np.ascontiguousarray(stored[..., i]) for i, name in enumerate("RGB")}).write(
        str(tmp_path / "window.exr"))
    y, x = np.mgrid[:10, :20]
    inside = (x >= x_min) & (x <= x_max) & (y >= y_min) & (y <= y_max)
    expected = np.where(inside[..., None], world[10:20, 10:30], 0)
    np.testing.assert_array_equal(read_exr(tmp_path / "window.exr").rgb(), expected)


def test_an_exr_with_no_stored_pixel_in_its_display_window_is_refused(tmp_path):
    header = {"type": OpenEXR.scanlineimage, "dataWindow": _box(30, 0, 39, 9), "displayWindow": _box(0, 0, 19, 9)}
    OpenEXR.File(header, {"Y": np.ones((10, 10), np.float32)}).write(str(tmp_path / "outside.exr"))
    with pytest.raises(InputError, match=r"outside.exr: no stored pixel lies in the image's frame"):
        read_exr(tmp_path / "outside.exr")


def test_a_small_file_declaring_a_huge_display_window_is_refused_before_decoding(tmp_path):
    from hdrcam.errors import TooLargeError

    header = {"type": OpenEXR.scanlineimage, "dataWindow": _box(0, 0, 0, 0), "displayWindow": _box(0, 0, 99999, 99999)}
    OpenEXR.File(header, {"Y": np.ones((1, 1), np.float32)}).write(str(tmp_path / "huge.exr"))
    with pytest.raises(TooLargeError, match=r"huge.exr: 1 channels over the display window \(100000 x 100000 px\)"):
        read_exr(tmp_path / "huge.exr")


@pytest.mark.parametrize("layers, image", [
    (("beauty",), "beauty"),  # one layer, prefixed (Nuke's and renderers' layer naming)
    (("ViewLayer.Combined", "ViewLayer.DiffCol"), "ViewLayer.Combined"),  # Blender's multi-layer render result
])
def test_colour_in_a_named_layer_is_read_from_the_images_layer(tmp_path, layers, image):
    """A file whose colour is in layers only (beauty.R, ViewLayer.Combined.R) was refused as having no R, G, B."""
    rng = np.random.default_rng(3)
    planes = {layer: rng.uniform(0, 4, (6, 8, 3)).astype(np.float32) for layer in layers}
    channels = {f"{layer}.{colour}": np.ascontiguousarray(rgb[..., i])
                for layer, rgb in planes.items() for i, colour in enumerate("RGB")}
    channels[f"{image}.A"] = np.ones((6, 8), np.float32)
    channels["ViewLayer.Depth.Z"] = np.full((6, 8), 7.0, np.float32)
    OpenEXR.File({"type": OpenEXR.scanlineimage}, channels).write(str(tmp_path / "layers.exr"))
    read = read_exr(tmp_path / "layers.exr")
    np.testing.assert_array_equal(read.rgb(), planes[image])
    np.testing.assert_array_equal(read.channels["A"], 1.0)


def test_several_colour_layers_none_of_them_the_image_are_refused_naming_them(tmp_path):
    channels = {f"{layer}.{colour}": np.ones((4, 4), np.float32)
                for layer in ("diffuse", "specular") for colour in "RGB"}
    OpenEXR.File({"type": OpenEXR.scanlineimage}, channels).write(str(tmp_path / "passes.exr"))
    with pytest.raises(InputError, match=r"passes.exr: colour layers diffuse, specular and no unprefixed R, G, B"):
        read_exr(tmp_path / "passes.exr")


@pytest.mark.parametrize("first", [
    ["depth.Z"],  # a part without colour first
    [f"{layer}.{colour}" for layer in ("diffuse", "specular") for colour in "RGB"],  # passes first: the first part
])  # with any colour layers was taken, and the file refused as having no known image
def test_a_multi_part_file_whose_image_is_a_named_layer_is_read_from_that_part(tmp_path, first):
    rgb = np.random.default_rng(4).uniform(0, 4, (6, 8, 3)).astype(np.float32)
    header = {"type": OpenEXR.scanlineimage}
    leading = OpenEXR.Part(dict(header, name="first"), {name: np.ones((6, 8), np.float32) for name in first})
    image = OpenEXR.Part(dict(header, name="beauty"), {f"beauty.{name}": np.ascontiguousarray(rgb[..., i])
                                                       for i, name in enumerate("RGB")})
    with OpenEXR.File([leading, image]) as exr:
        exr.write(str(tmp_path / "parts.exr"))
    np.testing.assert_array_equal(read_exr(tmp_path / "parts.exr").rgb(), rgb)


def test_a_lone_unprefixed_channel_beside_the_image_layer_is_refused_not_mixed_in(tmp_path):
    """R = 9 beside beauty.R/G/B = 1/2/3 read as [9, 2, 3]: the plain R overwrote the layer's."""
    channels = {f"beauty.{colour}": np.full((4, 4), value, np.float32) for colour, value in zip("RGB", (1, 2, 3))}
    channels["R"] = np.full((4, 4), 9.0, np.float32)
    OpenEXR.File({"type": OpenEXR.scanlineimage}, channels).write(str(tmp_path / "mixed.exr"))
    with pytest.raises(InputError, match=r"mixed.exr: unprefixed channel R beside the colour layer beauty"):
        read_exr(tmp_path / "mixed.exr")
