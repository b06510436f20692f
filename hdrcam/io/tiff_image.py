"""TIFF images as H x W x samples arrays in the file's sample order (R, G, B[, extra]), by tifffile.

OpenCV's TIFF decoder hands back the planes of a "per channel" file (PlanarConfiguration 2) as if they were
interleaved: such a frame came back scrambled with no error (a 16-bit planar TIFF reconstructed with unclipped
pixels up to 0.92 of white off). tifffile decodes both layouts, with imagecodecs' codecs (LZW, JPEG, the
predictors). Colour samples other than RGB (CMYK, CIELab, YCbCr left undecoded) are refused, not taken for RGB;
a file its codecs cannot decode is an InputError naming it, with tifffile's own log lines kept off stderr.
"""

from __future__ import annotations

import contextlib
import logging
from pathlib import Path

import numpy as np

from hdrcam.errors import InputError
from hdrcam.io.icc_profile import tone_curve_encoding
from hdrcam.limits import check_image_size

COLOUR_PHOTOMETRICS = ("RGB", "MINISBLACK", "MINISWHITE")  # RGB, or one sample (grey) refused by its callers
DECODED_COPY_BYTES = 12  # the float32 RGB image its callers make of the samples


def read_tiff_samples(path: Path) -> np.ndarray:
    """The first full-resolution image of a TIFF file: H x W x samples in the stored type (a one-sample image is H x W);
    InputError naming the file when it cannot be decoded or its samples are not RGB or grey."""
    import tifffile  # here: a GPU machine's training (tools/gpu) reads EXR and .hdr only, and lacks it

    try:
        with _tifffile_quiet(), tifffile.TiffFile(path) as tiff:
            page = _full_resolution_page(tiff)
            photometric = page.photometric.name if page.photometric is not None else "unknown"
            if photometric not in COLOUR_PHOTOMETRICS:
                raise InputError(f"{path}: TIFF of {photometric} samples, not RGB; save it as RGB")
            height, width = page.imagelength, page.imagewidth
            check_image_size(str(path), height, width, page.samplesperpixel * page.dtype.itemsize + DECODED_COPY_BYTES,
                             "give a smaller image")  # before decoding: a damaged header may declare anything
            samples = page.asarray()
            axes = page.axes
    except InputError:
        raise
    except MemoryError:
        raise
    except Exception as error:  # noqa: BLE001 - tifffile and its codecs raise their own (zlib.error, ...)
        raise InputError(f"{path}: cannot decode as TIFF ({type(error).__name__}: {error})") from None
    if axes.startswith("S") and samples.ndim == 3:  # planar: one plane per sample
        samples = np.moveaxis(samples, 0, -1)
    return samples


MULTI_PAGE = 2  # NewSubfileType bit 1 (TIFF 6.0, section 8): one page of a multi-page image, at full resolution


def is_full_resolution_image(page) -> bool:
    """Whether a tifffile page is a full-resolution image: NewSubfileType 0 (a DNG's raw image), or 2 (one page of
    a multi-page image). Any other bit makes it something else (TIFF 6.0, section 8; DNG 1.7): 1 a
    reduced-resolution copy (a thumbnail, a DNG's preview; 0x10001 an alternate one), 4 a transparency mask
    (0x10004 a DNG semantic mask), 8 a DNG depth map, 16 a DNG enhanced image, 32 a DNG gain map. tifffile reads
    the tag, or the older SubfileType (2: reduced, 3: a page)."""
    return not page.subfiletype & ~MULTI_PAGE


def _full_resolution_page(tiff):
    """The file's first full-resolution image: a writer may store a thumbnail first, which was read as the
    frame, or a transparency mask."""
    return next((page for page in tiff.pages if is_full_resolution_image(page)), tiff.pages[0])


ICC_PROFILE_TAG = 34675  # InterColorProfile (TIFF/EP, TIFF 6 technical note)


def tiff_nonlinear_encoding(path: Path) -> str | None:
    """What the first image's ICC profile says of a non-linear encoding ("an ICC profile (gamma 2.2)", from
    hdrcam.io.icc_profile), or None: no profile, or one whose tone curves are the identity (linear values).
    A file tifffile cannot open is left to :func:`read_tiff_samples` to name."""
    import tifffile

    try:
        with _tifffile_quiet(), tifffile.TiffFile(path) as tiff:
            tag = _full_resolution_page(tiff).tags.get(ICC_PROFILE_TAG)
            profile = bytes(tag.value) if tag is not None else None
    except Exception:  # noqa: BLE001 - read_tiff_samples names what is wrong with the file
        return None
    if profile is None:
        return None
    what = tone_curve_encoding(profile)
    return f"an ICC profile ({what})" if what else None


MAX_SAMPLE_VALUE_TAG = 281  # MaxSampleValue (TIFF 6.0, section 8)


def tiff_white_level(path: Path) -> int:
    """The white level of the first full-resolution image's unsigned-integer samples, by its tags: 2 **
    BitsPerSample - 1 (4095 for 12-bit samples, which tifffile gives as uint16 values up to 4095: divided by 65535
    they read 16x too dark, and clipped pixels as unclipped). InputError where a MaxSampleValue tag names another
    maximum: TIFF 6.0 makes it the largest value used, which a writer may mean as white (12-bit data in 16-bit
    samples) or as the image's own brightest value, so where white lies is not known."""
    import tifffile

    try:
        with _tifffile_quiet(), tifffile.TiffFile(path) as tiff:
            page = _full_resolution_page(tiff)
            bits, tag = int(page.bitspersample), page.tags.get(MAX_SAMPLE_VALUE_TAG)
            stated = np.atleast_1d(tag.value).astype(np.int64) if tag is not None else None
    except Exception as error:  # noqa: BLE001 - read_tiff_samples has read the file; this is the same file
        raise InputError(f"{path}: cannot decode as TIFF ({type(error).__name__}: {error})") from None
    white = 2 ** bits - 1
    if stated is not None and np.any(stated != white):
        raise InputError(f"{path}: the TIFF's MaxSampleValue tag says {', '.join(map(str, np.unique(stated)))} for "
                         f"{bits}-bit samples (white {white}), so its white level is not known; save the frame "
                         "with samples of as many bits as its data (white at the samples' largest value)")
    return white


def read_tiff_rgb(path: Path) -> np.ndarray:
    """A TIFF's H x W x 3 samples in R, G, B order and their stored type (extra samples such as alpha dropped);
    InputError naming the file when it holds fewer than three samples per pixel (grey)."""
    samples = read_tiff_samples(path)
    if samples.ndim != 3 or samples.shape[2] < 3:
        raise InputError(f"{path}: {'one sample' if samples.ndim == 2 else f'{samples.shape[2]} samples'} per pixel: "
                         "not an RGB image")
    return samples[..., :3]


@contextlib.contextmanager
def _tifffile_quiet():
    """tifffile logs what it finds wrong with a file as warnings on stderr; the InputError says it in one line."""
    logger = logging.getLogger("tifffile")
    level = logger.level
    logger.setLevel(logging.CRITICAL)
    try:
        yield
    finally:
        logger.setLevel(level)
