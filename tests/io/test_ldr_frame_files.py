"""Frames that are not RAW: which image files read_ldr_frame takes as linear, which it refuses, and what it warns."""

from __future__ import annotations

import shutil
import warnings

import cv2
import numpy as np
import pytest

from hdrcam.data.hdr_folder import read_hdr_image
from hdrcam.errors import InputError
from hdrcam.io.exr import write_exr
from hdrcam.io.ldr_frame import read_ldr_frame
from tests.io.icc_profiles import SRGB_PARAMETERS, curv, para, profile, rgb_curves


def _gradient() -> np.ndarray:
    return np.linspace(0.0, 1.0, 32 * 48 * 3, dtype=np.float32).reshape(32, 48, 3)


def test_a_float_tiff_is_linear_as_an_exr_and_a_jpeg_is_refused_as_gamma_encoded(tmp_path):
    frame = _gradient()
    cv2.imwrite(str(tmp_path / "frame.tif"), cv2.cvtColor(frame, cv2.COLOR_RGB2BGR))
    assert np.allclose(read_ldr_frame(tmp_path / "frame.tif"), frame)
    cv2.imwrite(str(tmp_path / "frame.jpg"), (frame * 255).astype(np.uint8))
    with pytest.raises(InputError, match="a JPEG is 8-bit and gamma-encoded"):
        read_ldr_frame(tmp_path / "frame.jpg")


def test_an_exr_without_its_suffix_is_read_as_an_exr(tmp_path):
    write_exr(tmp_path / "frame.exr", _gradient())
    shutil.copy(tmp_path / "frame.exr", tmp_path / "frame")
    assert np.array_equal(read_ldr_frame(tmp_path / "frame"), read_ldr_frame(tmp_path / "frame.exr"))


def test_a_16_bit_frame_clipped_below_65535_is_warned_about(tmp_path):
    counts = (_gradient() * 16383).astype(np.uint16)  # 14-bit data in a 16-bit file
    counts[:8, :8] = 16383  # a clipped light
    cv2.imwrite(str(tmp_path / "fourteen.png"), counts)
    with pytest.warns(UserWarning, match="pixels share the brightest value, 16383 of 65535"):
        read_ldr_frame(tmp_path / "fourteen.png")
    cv2.imwrite(str(tmp_path / "sixteen.png"), (counts.astype(np.uint32) * 4 + 3).clip(0, 65535).astype(np.uint16))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        read_ldr_frame(tmp_path / "sixteen.png")  # white at 65535: no warning


def test_an_8_bit_image_is_not_taken_as_an_hdr_scene_and_a_float_tiff_is(tmp_path):
    cv2.imwrite(str(tmp_path / "scene.png"), (_gradient() * 255).astype(np.uint8))
    with pytest.raises(InputError, match="scene.png: 8-bit pixels: a display image"):
        read_hdr_image(tmp_path / "scene.png")
    cv2.imwrite(str(tmp_path / "scene.tif"), cv2.cvtColor(_gradient() * 4000, cv2.COLOR_RGB2BGR))
    assert np.allclose(read_hdr_image(tmp_path / "scene.tif"), _gradient() * 4000)


@pytest.mark.parametrize("compression", [None, "zlib"])
def test_a_tiff_stored_plane_by_plane_reads_as_the_same_image(tmp_path, compression):
    """A "per channel" TIFF (PlanarConfiguration 2): OpenCV handed its planes back as if interleaved - a 16-bit
    frame read up to 0.92 of white off, a float scene by its peak - with no error."""
    import tifffile

    counts = (_gradient() * 60000).astype(np.uint16)
    scene = _gradient() * 40.0
    for name, image in (("frame", counts), ("scene", scene)):
        tifffile.imwrite(tmp_path / f"{name}-planar.tif", np.moveaxis(image, -1, 0), photometric="rgb",
                         planarconfig="separate", compression=compression)
        tifffile.imwrite(tmp_path / f"{name}-contiguous.tif", image, photometric="rgb", compression=compression)
    for layout in ("planar", "contiguous"):
        np.testing.assert_array_equal(read_ldr_frame(tmp_path / f"frame-{layout}.tif"),
                                      counts.astype(np.float32) / 65535.0)
        np.testing.assert_array_equal(read_hdr_image(tmp_path / f"scene-{layout}.tif"), scene)


def test_a_tiff_that_is_not_rgb_or_not_a_tiff_is_refused_in_one_line(tmp_path):
    import tifffile

    tifffile.imwrite(tmp_path / "grey.tif", np.ones((8, 8), np.float32))
    with pytest.raises(InputError, match=r"grey.tif: one sample per pixel: not an RGB image"):
        read_hdr_image(tmp_path / "grey.tif")
    with pytest.raises(InputError, match=r"grey.tif: one sample per pixel: not an RGB image"):
        read_ldr_frame(tmp_path / "grey.tif")
    (tmp_path / "text.tif").write_text("not a tiff")
    with pytest.raises(InputError, match=r"text.tif: cannot decode as TIFF"):
        read_ldr_frame(tmp_path / "text.tif")


def test_lzw_and_half_float_tiffs_read_and_damaged_or_cmyk_ones_are_refused_in_one_line(tmp_path, capfd):
    """OpenCV writes 16-bit TIFFs with LZW, which tifffile decodes only with imagecodecs; a corrupt deflate
    stream escaped as zlib.error (exit 3), four CMYK samples were read as RGB, and tifffile's log lines reached
    stderr."""
    import tifffile

    counts = (_gradient() * 60000).astype(np.uint16)
    cv2.imwrite(str(tmp_path / "lzw.tif"), cv2.cvtColor(counts, cv2.COLOR_RGB2BGR))
    assert tifffile.TiffFile(tmp_path / "lzw.tif").pages[0].compression == tifffile.COMPRESSION.LZW
    np.testing.assert_array_equal(read_ldr_frame(tmp_path / "lzw.tif"), counts / np.float32(65535.0))
    tifffile.imwrite(tmp_path / "half.tif", _gradient().astype(np.float16), photometric="rgb")
    np.testing.assert_allclose(read_ldr_frame(tmp_path / "half.tif"), _gradient(), atol=1e-3)

    tifffile.imwrite(tmp_path / "deflate.tif", counts, photometric="rgb", compression="zlib")
    data = bytearray((tmp_path / "deflate.tif").read_bytes())
    data[300:360] = bytes(60)  # inside the compressed strip (it starts at byte 272)
    (tmp_path / "deflate.tif").write_bytes(bytes(data))
    tifffile.imwrite(tmp_path / "cmyk.tif", np.concatenate([counts, counts[..., :1]], axis=-1),
                     photometric="separated")
    capfd.readouterr()
    for name, message in (("deflate.tif", "cannot decode as TIFF"), ("cmyk.tif", "TIFF of SEPARATED samples, not RGB")):
        for reader in (read_ldr_frame, read_hdr_image):
            with pytest.raises(InputError, match=f"{name}: {message}"):
                reader(tmp_path / name)
    assert capfd.readouterr().err == ""


def _png_chunk(kind: bytes, body: bytes) -> bytes:
    import struct
    import zlib

    return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF)


def _iccp(icc: bytes) -> bytes:
    import zlib

    return b"working space\x00\x00" + zlib.compress(icc)


def _png16_with_chunks(path, chunks: list[bytes]):
    """A 16-bit RGB PNG with ``chunks`` after its IHDR (where photo editors put sRGB and gAMA)."""
    image = (np.linspace(0, 65535, 48 * 64 * 3) % 65536).astype(np.uint16).reshape(48, 64, 3)
    data = cv2.imencode(".png", image)[1].tobytes()
    path.write_bytes(data[:33] + b"".join(chunks) + data[33:])  # 8-byte signature + 25-byte IHDR chunk
    return path


@pytest.mark.parametrize("chunks, said", [
    ([(b"sRGB", b"\x00")], "an sRGB chunk"),
    ([(b"gAMA", (45455).to_bytes(4, "big"))], "gAMA 0.45455"),
    ([(b"cICP", bytes([1, 13, 0, 1]))], "cICP transfer 13"),
])
def test_a_png_that_declares_itself_gamma_encoded_is_refused(tmp_path, chunks, said):
    """A 16-bit PNG from a photo editor (sRGB or gAMA 1/2.2 chunk) was read as linear with no word: a frame 2.6 x
    too bright in the mean, more pixels counted as clipped."""
    path = _png16_with_chunks(tmp_path / "frame.png", [_png_chunk(kind, body) for kind, body in chunks])
    with pytest.raises(InputError, match=f"frame.png: the PNG declares {said}.*: hdrcam reads linear values only"):
        read_ldr_frame(path)


@pytest.mark.parametrize("chunks", [[], [(b"gAMA", (100000).to_bytes(4, "big"))], [(b"cICP", bytes([1, 8, 0, 1]))]])
def test_a_png_without_or_with_a_linear_transfer_chunk_is_read(tmp_path, chunks):
    path = _png16_with_chunks(tmp_path / "frame.png", [_png_chunk(kind, body) for kind, body in chunks])
    assert read_ldr_frame(path).shape == (48, 64, 3)


def test_radiance_frames_read_as_linear_and_an_hdr_photograph_is_refused_as_one(tmp_path):
    """A Radiance file given to reconstruct got LibRaw's 'not RAW' line; an in-range one is a frame like an EXR."""
    frame = np.full((16, 16, 3), 0.25, np.float32)
    cv2.imwrite(str(tmp_path / "frame.hdr"), frame)
    np.testing.assert_allclose(read_ldr_frame(tmp_path / "frame.hdr"), 0.25, atol=0.01)
    frame[4:8, 4:8] = 40.0
    cv2.imwrite(str(tmp_path / "scene.hdr"), frame)
    shutil.copy(tmp_path / "scene.hdr", tmp_path / "scene-without-suffix")
    for name in ("scene.hdr", "scene-without-suffix"):
        with pytest.raises(InputError, match=f"{name}: values reach .*above white"):
            read_ldr_frame(tmp_path / name)


def test_a_jpeg_is_refused_as_one_whatever_its_name(tmp_path):
    (tmp_path / "IMG_0001").write_bytes(cv2.imencode(".jpg", np.full((8, 8, 3), 128, np.uint8))[1].tobytes())
    with pytest.raises(InputError, match="IMG_0001: a JPEG is 8-bit and gamma-encoded"):
        read_ldr_frame(tmp_path / "IMG_0001")


@pytest.mark.parametrize("chunks, refused", [
    ([(b"iCCP", b"sRGB profile\x00\x00" + bytes(20))], "an ICC profile"),  # damaged: not known to be linear
    ([(b"iCCP", _iccp(rgb_curves(curv()))), (b"sRGB", b"\x00")], None),  # a linear ICC profile over sRGB
    ([(b"cICP", bytes([1, 8, 0, 1])), (b"sRGB", b"\x00")], None),  # cICP takes precedence: linear
    ([(b"gAMA", (100000).to_bytes(4, "big")), (b"sRGB", b"\x00")], "an sRGB chunk"),  # sRGB over gAMA
])
def test_png_colour_chunks_are_read_by_the_specifications_precedence(tmp_path, chunks, refused):
    """The first colour chunk decides; cICP > iCCP > sRGB > gAMA."""
    path = _png16_with_chunks(tmp_path / "frame.png", [_png_chunk(kind, body) for kind, body in chunks])
    if refused is None:
        assert read_ldr_frame(path).shape == (48, 64, 3)
    else:
        with pytest.raises(InputError, match=f"declares {refused}"):
            read_ldr_frame(path)


def test_a_png_chunk_that_claims_gigabytes_is_skipped_not_read(tmp_path):
    """A damaged length (4 GB) was read into memory: MemoryError under an address-space limit."""
    import resource

    image = cv2.imencode(".png", np.zeros((8, 8, 3), np.uint16))[1].tobytes()
    damaged = image[:33] + (0xFFFFFFF0).to_bytes(4, "big") + b"tEXt" + b"junk" + image[33:]
    (tmp_path / "frame.png").write_bytes(damaged)
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    in_use = int(next(line for line in open("/proc/self/status") if line.startswith("VmSize")).split()[1]) << 10
    resource.setrlimit(resource.RLIMIT_AS, (in_use + (1 << 30), hard))  # 1 GB more than this process holds
    try:
        with pytest.raises(InputError, match="frame.png"):
            read_ldr_frame(tmp_path / "frame.png")
    finally:
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))


@pytest.mark.parametrize("icc, said", [(rgb_curves(para(3, *SRGB_PARAMETERS)), "gamma 2.4, piecewise"),
                                       (rgb_curves(curv(gamma=1.8)), "gamma 1.8"),
                                       (profile({b"A2B0": b"mft2" + bytes(100)}), "a LUT-based profile"),
                                       (rgb_curves(curv()), None)])
def test_a_tiff_or_png_whose_icc_profile_encodes_its_values_is_refused_a_linear_one_read(tmp_path, icc, said):
    """16-bit TIFFs from RAW converters embed their output profile (sRGB, ProPhoto's gamma 1.8): the TIFF's was not
    read, so such a frame was taken as linear with no word (mid-grey 0.5 read as 0.5 for 0.21), and a PNG's ICC
    profile was refused even when its curves are the identity (a converter's linear output)."""
    import tifffile

    counts = (np.arange(48 * 64 * 3) * 13 % 65536).astype(np.uint16).reshape(48, 64, 3)
    tifffile.imwrite(tmp_path / "frame.tif", counts, photometric="rgb", extratags=[(34675, 7, len(icc), icc, True)])
    _png16_with_chunks(tmp_path / "frame.png", [_png_chunk(b"iCCP", _iccp(icc))])
    for name, declared in (("frame.tif", f"the TIFF declares an ICC profile \\({said}"),
                           ("frame.png", f"the PNG declares an ICC profile \\(iCCP: {said}")):
        if said is None:
            assert read_ldr_frame(tmp_path / name).shape == (48, 64, 3)
        else:
            with pytest.raises(InputError, match=f"{name}: {declared}"):
                read_ldr_frame(tmp_path / name)
    if said is None:
        np.testing.assert_allclose(read_ldr_frame(tmp_path / "frame.tif"), counts / 65535.0, atol=1e-7)


def test_an_exr_frame_keeps_its_stored_primaries_so_a_channel_clipped_alone_stays_clipped(tmp_path):
    """A linear Rec. 2020 frame (a RAW developer's export names its primaries) was converted to Rec. 709 before the
    frame checks: a light clipped in red alone came back at 1.47 ("not an LDR capture") and dark greens at -0.23
    ("check how the file was made"). TIFF and PNG primaries are not applied either."""
    import OpenEXR

    rec2020 = (0.708, 0.292, 0.170, 0.797, 0.131, 0.046, 0.3127, 0.3290)
    frame = np.full((16, 24, 3), 0.2, np.float32)
    frame[:4, :4] = (1.0, 0.3, 0.2)  # a red lamp, clipped in red only
    frame[8:, 8:] = (0.0, 0.5, 0.0)  # a saturated green
    OpenEXR.File({"type": OpenEXR.scanlineimage, "chromaticities": rec2020}, {"RGB": frame}).write(
        str(tmp_path / "frame.exr"))
    np.testing.assert_array_equal(read_ldr_frame(tmp_path / "frame.exr"), frame)


def test_a_tiff_whose_first_image_is_a_thumbnail_reads_its_full_resolution_image(tmp_path):
    """A writer may store a reduced-resolution copy first (NewSubfileType bit 0): it was read as the frame."""
    import tifffile

    counts = (_gradient() * 65535).astype(np.uint16)
    with tifffile.TiffWriter(tmp_path / "frame.tif") as tiff:
        tiff.write(counts[::4, ::4], subfiletype=1, photometric="rgb")
        tiff.write(counts, photometric="rgb")
    np.testing.assert_array_equal(read_ldr_frame(tmp_path / "frame.tif"), counts / np.float32(65535))


def test_a_tiffs_full_resolution_image_is_neither_a_transparency_mask_nor_a_reduced_page_of_a_multi_page_file(
        tmp_path):
    """One rule for TIFF frames and a DNG's raw image (hdrcam.io.tiff_image.is_full_resolution_image): NewSubfileType
    0 or 2 (one page of a multi-page image). The TIFF reader took any page without bit 0, so a transparency mask (4)
    before the image was read as the frame (refused as MASK samples); raw.py's rule, the whole value 0, took no page
    of a multi-page file and fell back to its first page, a thumbnail (3)."""
    import tifffile

    counts = (_gradient() * 65535).astype(np.uint16)
    with tifffile.TiffWriter(tmp_path / "masked.tif") as tiff:
        tiff.write(counts[..., 0] > 30000, subfiletype=4)  # a bilevel transparency mask, written first
        tiff.write(counts, photometric="rgb")
    with tifffile.TiffWriter(tmp_path / "pages.tif") as tiff:
        tiff.write(counts[::4, ::4], subfiletype=3, photometric="rgb")  # a reduced page of a multi-page image
        tiff.write(counts, subfiletype=2, photometric="rgb")
        tiff.write(counts[::-1], subfiletype=2, photometric="rgb")
    for name in ("masked.tif", "pages.tif"):
        np.testing.assert_array_equal(read_ldr_frame(tmp_path / name), counts / np.float32(65535))


def test_grey_pngs_with_alpha_and_integer_tiffs_other_than_16_bit_unsigned_are_refused_for_what_they_are(tmp_path):
    """OpenCV expands a grey-and-alpha PNG to four channels: it read as an RGB frame (plain grey was refused).
    An int16 or uint32 TIFF was refused as "gamma-encoded"."""
    import tifffile

    import struct
    import zlib

    grey = (_gradient()[..., 0] * 65535).astype(">u2")
    samples = np.stack([grey, np.full_like(grey, 65535)], axis=-1)  # 16-bit grey and alpha (colour type 4)
    rows = b"".join(b"\0" + row.tobytes() for row in samples)  # filter type 0 per row

    def chunk(kind: bytes, body: bytes) -> bytes:
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    (tmp_path / "grey-alpha.png").write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(
        ">IIBBBBB", grey.shape[1], grey.shape[0], 16, 4, 0, 0, 0)) + chunk(b"IDAT", zlib.compress(rows)) +
        chunk(b"IEND", b""))
    assert cv2.imread(str(tmp_path / "grey-alpha.png"), cv2.IMREAD_UNCHANGED).shape == (*grey.shape, 4)
    with pytest.raises(InputError, match="a grey and alpha PNG"):
        read_ldr_frame(tmp_path / "grey-alpha.png")
    for dtype in (np.int16, np.uint32):
        tifffile.imwrite(tmp_path / "frame.tif", (_gradient() * 30000).astype(dtype), photometric="rgb")
        with pytest.raises(InputError, match=f"{np.dtype(dtype).name} samples, whose white level is unknown"):
            read_ldr_frame(tmp_path / "frame.tif")


def test_a_folder_of_radiance_pic_files_is_read_as_frames_are(tmp_path):
    """.pic (Radiance's own suffix) was read as a frame but left out of --data folders."""
    from hdrcam.data.hdr_folder import hdr_files

    scene = np.full((16, 16, 3), 2.0, np.float32)
    cv2.imwrite(str(tmp_path / "scene.hdr"), scene)
    (tmp_path / "scene.hdr").rename(tmp_path / "scene.pic")
    (tmp_path / "thumb.pic").write_bytes(b"\0" * 512 + b"\x00\x0aPICT")  # an Apple PICT picture, not Radiance
    assert [path.name for path in hdr_files(tmp_path)] == ["scene.pic"]


@pytest.mark.parametrize("compression", ["DWAA_COMPRESSION", "DWAB_COMPRESSION"])
def test_a_frame_whose_lossy_compression_rang_past_white_is_refused_naming_the_codec(tmp_path, compression):
    """A captured frame saved DWA-compressed rings about 2 % past white; it was refused as 'not an LDR capture
    (give the camera frame, not an HDR image)', though it is the camera frame."""
    import OpenEXR

    rng = np.random.default_rng(5)
    frame = np.clip(rng.uniform(0, 1.6, (64, 64, 3)), 0, 1).astype(np.float32)  # a third clipped, noisy
    OpenEXR.File({"type": OpenEXR.scanlineimage, "compression": getattr(OpenEXR, compression)},
                 {name: np.ascontiguousarray(frame[..., i]) for i, name in enumerate("RGB")}).write(
        str(tmp_path / "frame.exr"))
    name = compression.split("_")[0]
    with pytest.raises(InputError, match=rf"frame.exr: values (reach|down to) .*the EXR is {name}-compressed, a lossy "
                                         r"codec .*save the frame losslessly"):
        read_ldr_frame(tmp_path / "frame.exr")


def test_an_hdr_image_in_a_lossy_exr_is_still_called_an_hdr_image(tmp_path):
    import OpenEXR

    image = np.full((16, 16, 3), 0.5, np.float32)
    image[4:8, 4:8] = 40.0
    OpenEXR.File({"type": OpenEXR.scanlineimage, "compression": OpenEXR.DWAA_COMPRESSION},
                 {name: np.ascontiguousarray(image[..., i]) for i, name in enumerate("RGB")}).write(
        str(tmp_path / "hdr.exr"))
    with pytest.raises(InputError, match=r"above white \(1.0\): this is not an LDR capture"):
        read_ldr_frame(tmp_path / "hdr.exr")


@pytest.mark.parametrize("dtype, blamed", [(np.float16, True), (np.float32, False)])
def test_b44_is_blamed_only_where_it_altered_half_float_channels(tmp_path, dtype, blamed):
    """B44 is lossy on half channels only (float32 ones are stored as they are): a float32 B44 file 5 % above
    white was told its codec rang, though its values are exactly what was written."""
    import OpenEXR

    from hdrcam.io.exr import lossy_compression

    frame = np.full((32, 32, 3), 0.5, dtype)
    frame[8:12, 8:12] = 1.05  # past white by more than a capture's tolerance, well within a codec's ringing
    OpenEXR.File({"type": OpenEXR.scanlineimage, "compression": OpenEXR.B44_COMPRESSION},
                 {name: np.ascontiguousarray(frame[..., i]) for i, name in enumerate("RGB")}).write(
        str(tmp_path / "frame.exr"))
    assert lossy_compression(tmp_path / "frame.exr") == ("B44" if blamed else None)
    with pytest.raises(InputError, match="B44-compressed" if blamed else "this is not an LDR capture"):
        read_ldr_frame(tmp_path / "frame.exr")
