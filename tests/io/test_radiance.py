"""Radiance files against OpenCV's decoding of the same pixels in its standard form: orientations, header
corrections, XYZE, and one-line refusals (hdrcam.io.radiance)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from hdrcam.colorimetry import EQUAL_ENERGY_XYZ_CHROMATICITIES, to_rec709_matrix
from hdrcam.data.hdr_folder import read_hdr_image
from hdrcam.errors import InputError

HEIGHT, WIDTH = 6, 9
STANDARD_HEADER = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n"


def _image() -> np.ndarray:
    rng = np.random.default_rng(0)
    return (rng.uniform(0.01, 1, (HEIGHT, WIDTH, 3)) * 10 ** rng.uniform(-1, 3, (HEIGHT, WIDTH, 1))).astype(np.float32)


def _standard_bytes(tmp_path, stored: np.ndarray) -> bytes:
    """OpenCV's file of ``stored`` (RGB, top to bottom, left to right)."""
    cv2.imwrite(str(tmp_path / "standard.hdr"), cv2.cvtColor(stored, cv2.COLOR_RGB2BGR))
    data = (tmp_path / "standard.hdr").read_bytes()
    assert data.startswith(STANDARD_HEADER)
    return data


def _decoded(tmp_path, image: np.ndarray) -> np.ndarray:
    """``image`` as RGBE quantises it."""
    _standard_bytes(tmp_path, image)
    return cv2.cvtColor(cv2.imread(str(tmp_path / "standard.hdr"), cv2.IMREAD_ANYDEPTH | cv2.IMREAD_COLOR),
                        cv2.COLOR_BGR2RGB)


def _with_header(tmp_path, stored: np.ndarray, header: bytes, resolution: bytes):
    data = _standard_bytes(tmp_path, stored)
    pixels = data[data.index(b"\n", len(STANDARD_HEADER)) + 1:]
    (tmp_path / "file.hdr").write_bytes(header + b"\n" + resolution + b"\n" + pixels)
    return tmp_path / "file.hdr"


@pytest.mark.parametrize("resolution, stored", [
    (b"-Y %d +X %d" % (HEIGHT, WIDTH), lambda image: image),  # the standard: top to bottom, left to right
    (b"+Y %d +X %d" % (HEIGHT, WIDTH), lambda image: image[::-1]),  # bottom to top
    (b"-Y %d -X %d" % (HEIGHT, WIDTH), lambda image: image[:, ::-1]),  # right to left
    (b"+Y  %d  -X %d" % (HEIGHT, WIDTH), lambda image: image[::-1, ::-1]),  # (Radiance allows any white space)
    (b"+X %d -Y %d" % (WIDTH, HEIGHT), lambda image: image.transpose(1, 0, 2)),  # scanlines down the columns
    (b"+X %d +Y %d" % (WIDTH, HEIGHT), lambda image: image[::-1].transpose(1, 0, 2)),
    (b"-X %d -Y %d" % (WIDTH, HEIGHT), lambda image: image[:, ::-1].transpose(1, 0, 2)),
    (b"-X %d +Y %d" % (WIDTH, HEIGHT), lambda image: image[::-1, ::-1].transpose(1, 0, 2)),
])
def test_every_orientation_reads_as_the_image_it_stores(tmp_path, resolution, stored):
    """OpenCV refused any orientation but -Y H +X W ("cannot read as an HDR image")."""
    image = _image()
    path = _with_header(tmp_path, np.ascontiguousarray(stored(image)), b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n",
                        resolution)
    np.testing.assert_array_equal(read_hdr_image(path), _decoded(tmp_path, image))


def test_exposure_and_colour_corrections_are_divided_out_and_a_missing_format_means_rgbe(tmp_path):
    """Radiance: a file's values are radiance times EXPOSURE (every such line) and COLORCORR (per channel); they
    were ignored, so R:B read 4x off with COLORCORR=2 1 0.5."""
    image = _image()
    header = b"#?RADIANCE\n# a comment\nEXPOSURE=2\nCOLORCORR=2 1 0.5\nEXPOSURE=1.5\nSOFTWARE=test\n"
    path = _with_header(tmp_path, image, header, b"-Y %d +X %d" % (HEIGHT, WIDTH))
    np.testing.assert_allclose(read_hdr_image(path), _decoded(tmp_path, image) / np.array([6.0, 3.0, 1.5]),
                               rtol=1e-6)


def test_xyze_data_are_converted_from_equal_energy_xyz(tmp_path):
    xyz = _image()
    path = _with_header(tmp_path, xyz, b"#?RADIANCE\nFORMAT=32-bit_rle_xyze\n", b"-Y %d +X %d" % (HEIGHT, WIDTH))
    expected = _decoded(tmp_path, xyz) @ to_rec709_matrix(EQUAL_ENERGY_XYZ_CHROMATICITIES).T
    np.testing.assert_allclose(read_hdr_image(path), np.clip(expected, 0, None), rtol=1e-5, atol=1e-6)
    grey = np.full((2, 2, 3), 3.0, np.float32)  # equal-energy white reads as neutral
    path = _with_header(tmp_path, grey, b"#?RADIANCE\nFORMAT=32-bit_rle_xyze\n", b"-Y 2 +X 2")
    np.testing.assert_allclose(read_hdr_image(path), 3.0, rtol=1e-5)


@pytest.mark.parametrize("header, resolution, message", [
    (b"#?RADIANCE\nFORMAT=32-bit_rle_rgbf\n", b"-Y 6 +X 9", r"FORMAT=32-bit_rle_rgbf is not one of"),
    (b"#?RADIANCE\n", b"-Y 6 -Y 9", r"resolution line '-Y 6 -Y 9' is not"),
    (b"#?RADIANCE\nCOLORCORR=2 1\n", b"-Y 6 +X 9",
     r"COLORCORR= needs 3 positive finite numbers from 1e-30 to 1e\+30, got .2 1."),
    (b"#?RADIANCE\nEXPOSURE=abc\n", b"-Y 6 +X 9", r"EXPOSURE=abc is not numbers"),
    (b"#?RADIANCE\nEXPOSURE=1e300\n", b"-Y 6 +X 9", r"EXPOSURE= needs 1 positive finite numbers from 1e-30"),
    (b"#?RADIANCE\nPRIMARIES=nan 0.33 0.3 0.6 0.15 0.06 0.3127 0.329\n", b"-Y 6 +X 9", r"PRIMARIES= needs 8 finite"),
    (b"#?RADIANCE\n", b"-Y 70000 +X 70000", r"file.hdr \(70000 x 70000 px\) needs about"),
])
def test_an_unusable_header_is_refused_in_one_line_that_says_why(tmp_path, header, resolution, message):
    path = _with_header(tmp_path, _image(), header, resolution)
    with pytest.raises(InputError, match=message):
        read_hdr_image(path)


def test_truncated_pixel_data_are_refused(tmp_path):
    path = _with_header(tmp_path, _image(), b"#?RADIANCE\n", b"-Y 6 +X 9")
    path.write_bytes(path.read_bytes()[:60])
    with pytest.raises(InputError, match="pixel data cannot be decoded"):
        read_hdr_image(path)


def test_corrections_that_multiply_beyond_float32_are_refused_in_one_line(tmp_path):
    """Each EXPOSURE line was checked alone, but the lines multiply: two of 1e-20 put inf in every pixel with
    numpy's overflow warning on stderr."""
    path = _with_header(tmp_path, _image(), b"#?RADIANCE\nEXPOSURE=1e-20\nEXPOSURE=1e-20\n", b"-Y 6 +X 9")
    with pytest.raises(InputError, match=r"EXPOSURE and COLORCORR lines multiply to 1e-40, 1e-40, 1e-40"):
        read_hdr_image(path)


def _colr(image: np.ndarray) -> np.ndarray:
    """``image``'s 4-byte pixels as Radiance's setcolr (and OpenCV) encode them: mantissas truncated."""
    largest = image.max(axis=-1)
    fraction, exponent = np.frexp(largest)
    scale = np.where(largest > 1e-32, fraction * 256.0 / np.maximum(largest, 1e-32), 0.0)
    colr = np.zeros(image.shape[:2] + (4,), np.uint8)
    colr[..., :3] = (image * scale[..., None]).astype(np.uint8)
    colr[..., 3] = np.where(largest > 1e-32, exponent + 128, 0)
    return colr


def _old_style_runs(colr: np.ndarray) -> bytes:
    """Scanlines in Radiance's old-style run-length encoding: after a pixel, 1, 1, 1, n repeats it n times; a
    second such record in a row counts in units of 256."""
    out = bytearray()
    for row in colr:
        x = 0
        while x < len(row):
            out += row[x].tobytes()
            run = 1
            while x + run < len(row) and (row[x + run] == row[x]).all():
                run += 1
            if run > 1:
                out += bytes([1, 1, 1, (run - 1) & 255]) + (bytes([1, 1, 1, (run - 1) >> 8]) if run > 256 else b"")
            x += run
    return bytes(out)


def test_old_style_run_length_scanlines_read_as_the_pixels_they_repeat(tmp_path):
    """Radiance's first run-length encoding (pixels 1, 1, 1, n repeat the one before; "Radiance File Formats",
    color.c oldreadcolrs), as pre-1991 Radiance files hold: OpenCV refused them ("pixel data cannot be
    decoded"). Scanlines 300 pixels long, one of them a run of 299 repeats (counted in two records)."""
    image = np.repeat(_image()[:, :1], 300, axis=1)
    image[:, 100:140] = _image()[:, :1] * 0.5
    image[1, 5:9] = _image()[1, 3]
    colr = _colr(image)
    flat = tmp_path / "flat.hdr"
    flat.write_bytes(STANDARD_HEADER + b"-Y %d +X 300\n" % HEIGHT + colr.tobytes())  # OpenCV reads flat files
    runs = tmp_path / "runs.hdr"
    runs.write_bytes(STANDARD_HEADER + b"-Y %d +X 300\n" % HEIGHT + _old_style_runs(colr))
    expected = cv2.cvtColor(cv2.imread(str(flat), cv2.IMREAD_ANYDEPTH | cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    np.testing.assert_array_equal(read_hdr_image(runs), expected)
    np.testing.assert_array_equal(read_hdr_image(flat), expected)


def test_a_flat_file_cut_in_its_pixels_names_the_scanline(tmp_path):
    path = tmp_path / "cut.hdr"
    path.write_bytes(STANDARD_HEADER + b"-Y %d +X %d\n" % (HEIGHT, WIDTH) + _colr(_image()).tobytes()[:-10])
    with pytest.raises(InputError, match=r"cut.hdr: Radiance pixel data cannot be decoded: scanline 6 of 6: the "
                                         r"file ends inside it \(truncated\)"):
        read_hdr_image(path)


@pytest.mark.parametrize("data, message", [
    (b"#?RADIANCE\r\nFORMAT=32-bit_rle_rgbe\r\n\r\n-Y 6 +X 9\r\n" + bytes(216),
     r"crlf.hdr: Radiance header lines end in CR LF, not LF: a copy made in text mode"),
    (b"#?RADIANCE\r\nFORMAT=32-bit_rle_rgbe\r\n\r\n-Y 6 +X 9\r\n" + bytes(100) + b"\n\n" + bytes(114),
     r"crlf.hdr: Radiance header lines end in CR LF"),  # LF LF in the pixels: it was read as a resolution line
    (b"P6\n9 6\n255\n" + bytes(162), r"crlf.hdr: not a Radiance file \(it does not start with the '#\?' magic line\)"),
    (b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n-Y 6 +X 9\n", r"crlf.hdr: not a Radiance file \(no empty line ends its"),
])
def test_a_file_that_is_not_radiance_says_what_it_lacks(tmp_path, data, message):
    """A header with CR LF line ends (a text-mode copy) was called a file with 'no '#?' magic line and header
    ending in an empty line', though it has the magic line."""
    from hdrcam.io.radiance import read_radiance

    (tmp_path / "crlf.hdr").write_bytes(data)
    with pytest.raises(InputError, match=message):
        read_radiance(tmp_path / "crlf.hdr")
