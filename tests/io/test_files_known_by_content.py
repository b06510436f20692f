"""Which reader a frame (read_ldr_frame) or a scene (read_hdr_image) goes to: its first bytes before its name;
a Radiance frame's primaries as stored; a TIFF's white level from its tags; what is said of a file that is
empty, of another format than its name says, or not a regular file."""

from __future__ import annotations

import os
import shutil
import warnings

import cv2
import numpy as np
import pytest

from hdrcam.colorimetry import to_rec709_matrix
from hdrcam.data.hdr_folder import read_hdr_image
from hdrcam.errors import InputError
from hdrcam.io.exr import read_exr
from hdrcam.io.ldr_frame import frame_format, read_ldr_frame

REC2020 = (0.708, 0.292, 0.170, 0.797, 0.131, 0.046, 0.3127, 0.3290)


def _gradient(height: int = 32, width: int = 48) -> np.ndarray:
    """R rises left to right, G top to bottom, B = 0.3: a frame whose layout and channels a mix-up shows."""
    y, x = np.mgrid[0:height, 0:width].astype(np.float32)
    return np.stack([(x + 1) / width * 0.8, (y + 1) / height * 0.8, np.full_like(x, 0.3)], -1)


def _radiance(path, rgb: np.ndarray, header_line: bytes = b"") -> np.ndarray:
    """Write ``rgb`` as a Radiance file (OpenCV's, ``header_line`` added to its header); the values it stores, as
    OpenCV decodes the file without that line."""
    cv2.imwrite(str(path), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    stored = cv2.cvtColor(cv2.imread(str(path), cv2.IMREAD_ANYDEPTH | cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    data = path.read_bytes()
    end = data.index(b"\n\n")
    path.write_bytes(data[:end + 1] + header_line + data[end + 1:])
    return stored


def test_a_radiance_frame_keeps_its_stored_primaries_as_an_exr_frame_does(tmp_path):
    """PRIMARIES= was converted to Rec. 709 for a frame: a red light clipped in red alone came back at -0.47 in
    green and the frame was refused as damaged, and an unclipped frame read 13 % off. A scene still converts."""
    frame = _gradient()
    frame[8:16, 8:16] = (1.0, 0.05, 0.05)  # a red light, clipped in red only
    stored = _radiance(tmp_path / "frame.hdr", frame, b"PRIMARIES= " + " ".join(map(str, REC2020)).encode() + b"\n")
    assert stored[10, 10, 0] == 1.0
    np.testing.assert_array_equal(read_ldr_frame(tmp_path / "frame.hdr"), stored)
    np.testing.assert_allclose(read_hdr_image(tmp_path / "frame.hdr"),
                               np.clip(stored @ to_rec709_matrix(REC2020).T, 0, None), rtol=1e-6, atol=1e-7)
    xyz = _radiance(tmp_path / "xyz.hdr", _gradient() * 0.5, b"FORMAT=32-bit_rle_xyze\n")  # XYZ, as stored too
    np.testing.assert_array_equal(read_ldr_frame(tmp_path / "xyz.hdr"), xyz)


def test_a_tiff_named_as_another_format_is_read_as_a_tiff(tmp_path):
    """A planar TIFF named .png went to OpenCV and came back scrambled (0.98 of white off) with exit 0; one named
    .hdr was a scene with its planes interleaved. A TIFF named as a RAW format is still LibRaw's (DNG is TIFF)."""
    import tifffile

    counts = np.round(_gradient() / 0.8 * 65535).astype(np.uint16)  # up to white: no plateau below it
    scene = _gradient() * 40.0
    scene[3, 30] = (60.0, 10.0, 2.0)
    tifffile.imwrite(tmp_path / "frame.png", np.moveaxis(counts, -1, 0), photometric="rgb", planarconfig="separate")
    tifffile.imwrite(tmp_path / "scene.hdr", np.moveaxis(scene, -1, 0), photometric="rgb", planarconfig="separate")
    shutil.copy(tmp_path / "frame.png", tmp_path / "frame.exr")
    for name in ("frame.png", "frame.exr"):
        np.testing.assert_array_equal(read_ldr_frame(tmp_path / name), counts.astype(np.float32) / 65535.0)
    np.testing.assert_array_equal(read_hdr_image(tmp_path / "scene.hdr"), scene)
    shutil.copy(tmp_path / "frame.png", tmp_path / "frame.dng")
    assert frame_format(tmp_path / "frame.dng", ".dng") is None  # LibRaw's
    assert frame_format(tmp_path / "frame.png", ".png") == "TIFF"


def test_a_radiance_file_named_exr_is_read_as_radiance(tmp_path):
    """It was refused as "not a readable OpenEXR file (Unable to open '<python_buffer>' for read)"."""
    stored = _radiance(tmp_path / "frame.hdr", _gradient())
    shutil.copy(tmp_path / "frame.hdr", tmp_path / "frame.exr")
    np.testing.assert_array_equal(read_ldr_frame(tmp_path / "frame.exr"), stored)
    np.testing.assert_array_equal(read_hdr_image(tmp_path / "frame.exr"), stored)


def test_a_file_that_is_not_what_its_name_says_or_empty_is_named_for_what_it_is(tmp_path):
    """A JPEG, a PNG, a zero-byte file or text named .exr were all refused with OpenEXR's internal stream name,
    "Unable to open '<python_buffer>' for read"."""
    jpeg = cv2.imencode(".jpg", np.full((8, 8, 3), 128, np.uint8))[1].tobytes()
    png = cv2.imencode(".png", np.full((8, 8, 3), 128, np.uint8))[1].tobytes()
    for name, data in (("jpeg.exr", jpeg), ("png.exr", png), ("empty.exr", b""), ("text.exr", b"not an image\n")):
        (tmp_path / name).write_bytes(data)
    (tmp_path / "empty.ARW").write_bytes(b"")
    expected = {
        ("jpeg.exr", read_ldr_frame): "a JPEG is 8-bit and gamma-encoded, not linear; give a RAW file, an EXR or a "
                                      "16-bit TIFF/PNG",
        ("png.exr", read_ldr_frame): "uint8 pixels are gamma-encoded, not linear; give a 16-bit TIFF/PNG, an EXR or "
                                     "a RAW file",
        ("empty.exr", read_ldr_frame): "an empty file (0 bytes)",
        ("empty.ARW", read_ldr_frame): "an empty file (0 bytes)",
        ("empty.exr", read_hdr_image): "an empty file (0 bytes)",
        ("png.exr", read_hdr_image): "8-bit pixels: a display image, gamma-encoded and clipped, not linear radiance; "
                                     "give an OpenEXR, Radiance .hdr or float TIFF",
        ("jpeg.exr", read_exr): "a JPEG, not an OpenEXR file",
        ("png.exr", read_exr): "a PNG, not an OpenEXR file",
        ("empty.exr", read_exr): "an empty file (0 bytes)",
        ("text.exr", read_exr): "not an OpenEXR file (it does not start with OpenEXR's magic bytes)",
        ("text.exr", read_ldr_frame): "not an OpenEXR file (it does not start with OpenEXR's magic bytes)",
    }
    for (name, reader), reason in expected.items():
        with pytest.raises(InputError) as raised:
            reader(tmp_path / name)
        assert str(raised.value) == f"{tmp_path / name}: {reason}", (name, reader.__name__)


def test_a_device_or_a_fifo_is_named_as_not_a_regular_file_not_as_missing(tmp_path):
    """/dev/null and a FIFO were "does not exist" / "no such file" (and a FIFO must not be opened: it blocks)."""
    os.mkfifo(tmp_path / "fifo.exr")
    for path in (tmp_path / "fifo.exr", "/dev/null"):
        for reader in (read_ldr_frame, read_hdr_image, read_exr):
            with pytest.raises(InputError) as raised:
                reader(path)
            assert str(raised.value) == f"{path}: not a regular file (a device, pipe or socket)", reader.__name__


@pytest.mark.parametrize("bits", [10, 12, 14])
def test_a_tiff_of_fewer_than_16_bits_is_scaled_by_its_own_white(tmp_path, bits):
    """A 12-bit TIFF was divided by 65535: 16x too dark, and its clipped light (4095) not seen as clipped."""
    import tifffile

    white = 2 ** bits - 1
    counts = np.round(_gradient() * white).astype(np.uint16)
    counts[8:16, 8:16] = white  # a clipped light
    tifffile.imwrite(tmp_path / "frame.tif", counts, photometric="rgb", bitspersample=bits)
    assert tifffile.imread(tmp_path / "frame.tif").max() == white
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the clipped light is at white: no "clipping below white?" warning
        frame = read_ldr_frame(tmp_path / "frame.tif")
    np.testing.assert_array_equal(frame, counts.astype(np.float32) / float(white))
    assert np.all(frame[8:16, 8:16] == 1.0)


def test_a_tiff_whose_max_sample_value_contradicts_its_bits_is_refused_and_one_that_agrees_read(tmp_path):
    import tifffile

    counts = np.round(_gradient() * 4095).astype(np.uint16)
    tifffile.imwrite(tmp_path / "stated.tif", counts, photometric="rgb", extratags=[(281, "H", 3, (4095,) * 3, True)])
    with pytest.raises(InputError) as raised:
        read_ldr_frame(tmp_path / "stated.tif")
    assert str(raised.value) == (f"{tmp_path / 'stated.tif'}: the TIFF's MaxSampleValue tag says 4095 for 16-bit "
                                 "samples (white 65535), so its white level is not known; save the frame with samples "
                                 "of as many bits as its data (white at the samples' largest value)")
    counts = np.round(_gradient() / 0.8 * 65535).astype(np.uint16)
    tifffile.imwrite(tmp_path / "agrees.tif", counts, photometric="rgb", extratags=[(281, "H", 3, (65535,) * 3, True)])
    np.testing.assert_array_equal(read_ldr_frame(tmp_path / "agrees.tif"), counts.astype(np.float32) / 65535.0)


def test_a_wide_gamut_value_near_float32s_limit_is_refused_in_one_line_not_overflowed(tmp_path):
    """Rec. 2020 R = 3e38 became +Inf in the matrix to Rec. 709 (after the finite check), with numpy's "overflow
    encountered in matmul"; evaluate then failed with "internal error: ValueError: high <= 0"."""
    import OpenEXR

    photo = _gradient() * 10.0
    photo[5, 5] = (3e38, 1.0, 1.0)
    OpenEXR.File({"type": OpenEXR.scanlineimage, "chromaticities": REC2020}, {"RGB": photo}).write(
        str(tmp_path / "wide.exr"))
    for lenient in (False, True):
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            with pytest.raises(InputError) as raised:
                read_hdr_image(tmp_path / "wide.exr", infinite_as_peak=lenient)
        assert str(raised.value) == (f"{tmp_path / 'wide.exr'}: its values (up to 3e+38) leave float32's range "
                                     "(3.4e+38) once its primaries are converted to Rec. 709; scale the image down "
                                     "(its absolute scale does not matter to hdrcam)")
    photo[5, 5] = (3e37, 1.0, 1.0)  # within range once converted: read, converted as before
    OpenEXR.File({"type": OpenEXR.scanlineimage, "chromaticities": REC2020}, {"RGB": photo}).write(
        str(tmp_path / "wide.exr"))
    np.testing.assert_allclose(read_hdr_image(tmp_path / "wide.exr"),
                               np.clip(photo @ to_rec709_matrix(REC2020).T, 0, None), rtol=1e-6, atol=1e-6)
