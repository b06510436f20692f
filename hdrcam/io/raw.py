"""Read RAW frames - any file LibRaw opens - with rawpy.

``read_raw_metadata`` gives what a bracket needs to know (exposure, ISO, aperture, time, levels, colour);
``read_raw`` adds the Bayer data: the visible area in digital numbers (uint16), untouched - no black
subtraction, no demosaicing - and the clip level measured from it (``hdrcam.io.raw_clipping``). LibRaw
does not report ISO for DNGs, nor the camera's make and model; they are read from the TIFF tags (ARW, NEF,
CR2, DNG, ... are TIFF files) when LibRaw has nothing, and a capture manifest can override ISO.

The pixels stay in the sensor's orientation (the PSF is measured and the CFA is laid out there);
``RawMetadata.orientation`` says how to display them (the EXIF Orientation code, from LibRaw's ``sizes.flip``).

Refused with one line naming the file: what LibRaw cannot open (with LibRaw's reason), a greyscale TIFF image
(a raw developer's black-and-white export, which LibRaw takes for a mosaic RAW: :func:`_is_greyscale_image`),
a Phase One IIQ (LibRaw leaves its black level out of the undeveloped data: :func:`_is_phase_one`), sensors that are
not a 2 x 2 Bayer mosaic on a square grid (X-Trans 6 x 6, Foveon and linear DNGs, four-colour CFAs, a DNG's
Quad-Bayer, Nona-Bayer or staggered CFA, a visible area LibRaw places outside its raw data),
and truncated files. Some of LibRaw's decoders fill a truncated file's missing rows by
repeating the last row they decoded and report no error (an A7R III ARW cut to half decodes with its last 1787
rows identical), so a TIFF-based file (ARW, NEF, CR2, DNG, ...) is refused when its strips or tiles run past
the end of the file, and a file of another format (CR3, RAF, ...) when its last FILLED_ROWS or more rows repeat
one row that is not flat (a sensor's noise never repeats a row bit for bit). An uncompressed strip needs its
rows' bytes, whatever its byte count says beyond them; a compressed strip whose count is at least its
uncompressed size is not believed (older Hasselblad 3FRs declare the uncompressed size, past the end of the
file: exiftool/exiftool#476), and such a file is checked by its rows as a CR3 is (not verified on a real
3FR: LibRaw's Hasselblad decoder may fill what is missing without repeating rows). LibRaw's other decoders stop
at the end of the file with an "Input/output error", refused as a truncation too.

Colour (XYZ -> camera, D65): a DNG's own ColorMatrix tags first (the one calibrated for D65, else
ColorMatrix2, else ColorMatrix1), then LibRaw's table for the model (LibRaw reports zeros for a model it
does not know, whatever the DNG says); a missing, zero or singular matrix falls through to the next; with
none left, camera RGB (``colour_matrix_source`` says which, and users of the matrix warn). A DNG's matrix is
the whole transform of the DNG model, AnalogBalance x CameraCalibration x ColorMatrix (the calibration only
when its CameraCalibrationSignature matches the ProfileCalibrationSignature, as the DNG spec 1.2+ asks;
phones' DNGs carry a per-unit calibration). A DNG that gives its as-shot white as AsShotWhiteXY instead of
AsShotNeutral (LibRaw then reports no white balance) gets the neutral that white gives through the colour
matrix (the DNG's, or LibRaw's table for the model).
A file that records no as-shot white at all (a DNG with neither tag: LibRaw's camera_whitebalance [0, 1, 0, 0])
is taken as shot in daylight - the neutral of D65 through its matrix, as LibRaw's
LIBRAW_PROCESSING_CAMERAWB_FALLBACK_TO_DAYLIGHT does (rawpy's ``daylight_whitebalance``) - and
``white_balance_source`` says so (its users warn); ones gave a strong green cast.

Black (DNG): the BlackLevel tags themselves, as floats (:func:`_dng_black_tile`): LibRaw rounds a fractional
BlackLevel to whole DN and, where the file has MaskedAreas, replaces the tags' level by its own whole-DN
measurement of those areas (shadows 7-18 % too bright: a level 1 DN low at 6-12 DN of signal). Other formats:
LibRaw's black level per colour.
"""

from __future__ import annotations

import contextlib
import dataclasses
import datetime as dt
import functools
import logging
import math
import os
import threading
import warnings
from pathlib import Path

import numpy as np
import tifffile

from hdrcam.errors import InputError
from hdrcam.io.c_stderr import c_stderr_silenced
from hdrcam.io.dng_opcodes import shading_opcodes
from hdrcam.io.tiff_image import is_full_resolution_image
from hdrcam.limits import check_image_size

_CFA_LETTERS = "RGBG"  # LibRaw colour indices: 0 R, 1 G, 2 B, 3 second G
NO_COLOUR_MATRIX = "none (camera RGB)"
AS_SHOT = "as shot"
DAYLIGHT_ASSUMED = "daylight (assumed: the file records no as-shot white)"
NO_WHITE_BALANCE = "none"
_D65_XY = (0.3127, 0.3290)  # CIE 1931 chromaticity of D65, sRGB's white (IEC 61966-2-1), which LibRaw's daylight
# white balance maps to camera RGB (its rgb_cam is XYZ -> camera times sRGB -> XYZ)
UNKNOWN_CAMERA = "unknown"
EPOCH_YEAR = 1970  # rawpy turns LibRaw's timestamp 0 (none recorded) into 1970-01-01
_MIN_MATRIX_DETERMINANT = 1e-6
_D65 = 21  # EXIF LightSource code, as in CalibrationIlluminant
FILLED_ROWS = 8
LIBRAW_HEADER_BYTES = 64  # LibRaw reads this much of a file to tell its format
_EXIF_ORIENTATION = {0: 1, 1: 2, 2: 4, 3: 3, 4: 5, 5: 8, 6: 6, 7: 7}  # LibRaw's sizes.flip -> EXIF (_exif_orientation)
_BLOCK_BAYER_NAMES = {2: "Quad-Bayer", 3: "Nona-Bayer"}  # each colour of a 2 x 2 Bayer tile on n x n pixels


class NotRawError(InputError):
    """A file LibRaw does not open as RAW (a sidecar, a JPEG, an unknown format)."""


@dataclasses.dataclass(frozen=True)
class RawMetadata:
    """What is known about one RAW exposure without its pixels."""

    path: Path
    width_px: int
    height_px: int
    raw_size_px: tuple[int, int]  # LibRaw's raw data, width x height: the visible area and the masked border
    cfa_pattern: str  # the 2 x 2 tile starting at the top-left visible pixel, e.g. "RGGB"
    black_level_dn: tuple[float, float, float, float]  # per tile position, row-major like cfa_pattern
    white_level_dn: float  # the metadata's white level; the sensor may clip below it (see clip levels)
    xyz_to_camera: np.ndarray  # 3 x 3, D65; the identity when colour_matrix_source is NO_COLOUR_MATRIX
    as_shot_neutral: np.ndarray  # camera RGB of white, max 1
    exposure_s: float
    iso: float | None
    f_number: float | None
    timestamp: dt.datetime | None
    camera_model: str  # make and model, e.g. "Sony ILCE-7RM3"
    make: str = UNKNOWN_CAMERA
    file_format: str = "unknown"  # "DNG", else the file's suffix, e.g. "ARW"
    colour_matrix_source: str = "LibRaw"  # "LibRaw", "DNG ColorMatrix1/2" or NO_COLOUR_MATRIX
    white_balance_source: str = AS_SHOT  # AS_SHOT (the file's, or its AsShotWhiteXY), DAYLIGHT_ASSUMED, or
    # NO_WHITE_BALANCE (neither a white nor a usable matrix: as_shot_neutral is ones)
    shading_not_applied: tuple[str, ...] = ()  # DNG lens-shading opcodes left out (hdrcam.io.dng_opcodes)
    orientation: int = 1  # EXIF Orientation code (1 to 8) that displays the frame upright (6: turn 90 degrees
    # clockwise); the pixels and every size above stay in the sensor's orientation

    def black_level_tile(self) -> np.ndarray:
        """The 2 x 2 tile of black levels (float32), row-major like ``cfa_pattern``."""
        return np.asarray(self.black_level_dn, dtype=np.float32).reshape(2, 2)

    @property
    def has_colour_matrix(self) -> bool:
        return self.colour_matrix_source != NO_COLOUR_MATRIX


@dataclasses.dataclass(frozen=True)
class RawFrame:
    metadata: RawMetadata
    bayer_dn: np.ndarray  # H x W uint16

    @functools.cached_property
    def clip_level_tile_dn(self) -> np.ndarray:
        """2 x 2 float32 tile (like ``cfa_pattern``) of the measured clip level in DN: every sample at or above
        its position's value is clipped. The pile-up below the metadata white level where there is one."""
        from hdrcam.io.raw_clipping import measure_clip_levels

        meta = self.metadata
        return measure_clip_levels(self.bayer_dn, meta.black_level_tile(), meta.white_level_dn)


def read_raw_metadata(path: str | Path) -> RawMetadata:
    """Metadata of a RAW file; InputError for a missing, damaged or non-Bayer file."""
    return _read(Path(path), with_pixels=False)[0]


def raw_size_px(path: str | Path) -> tuple[int, int] | None:
    """(raw width, raw height) in pixels from LibRaw's header alone (nothing is decoded), or None for a file LibRaw
    does not open: reading it in full reports why."""
    import rawpy

    raw = rawpy.RawPy()
    try:
        with c_stderr_silenced(), _libraw_path(Path(path)) as libraw_path:
            raw.open_file(libraw_path)
        return int(raw.sizes.raw_width), int(raw.sizes.raw_height)
    except (rawpy.LibRawUnsufficientMemoryError, rawpy.LibRawMemPoolOverflowError) as error:
        raise MemoryError(f"LibRaw opening {Path(path).name}: {_libraw_reason(error)}") from None
    except Exception:  # LibRaw raises many types for files it does not open
        return None
    finally:
        raw.close()


RAW_BYTES_PER_PIXEL = 16  # LibRaw's buffer (uint16, kept: the frame is a view of it) and the frame's share of the
# merge (float32 rate and variance, a mask) and of the demosaiced float32 RGB


def read_raw(path: str | Path) -> RawFrame:
    """A RAW file's metadata and Bayer digital numbers; InputError also for a black level above the data."""
    metadata, bayer = _read(Path(path), with_pixels=True)
    _check_no_dead_rows(metadata, bayer)  # first: zero-filled rows also pull a site's median below black
    _check_black_below_data(metadata, bayer)
    return RawFrame(metadata, bayer)


BLACK_CHECK_STRIDE = 7  # every 7th row and column of each CFA position: the median of ~120k samples at 24 MP
BLACK_ABOVE_DATA_TOLERANCE = 0.01  # of the black-to-white range: read noise is ~1e-4 of it at base ISO
DEAD_ROW_FRACTION_OF_BLACK = 0.5  # a flat row below this fraction of black holds no data


def _check_no_dead_rows(meta: RawMetadata, bayer_dn: np.ndarray) -> None:
    """InputError when FILLED_ROWS or more rows hold one value below half the black level in every sample: a
    sensor row always has noise around black at least, so such rows are no data - a file whose data was
    zero-filled on the card or in a copy, which its TIFF strips do not reveal (rows that vary below black are a
    black level above the data: :func:`_check_black_below_data`). Judged against black alone, not the white level
    (a DNG's default 65535 over 14-bit data would move a threshold drawn from the range)."""
    floor_dn = DEAD_ROW_FRACTION_OF_BLACK * float(meta.black_level_tile().min())
    brightest = bayer_dn.max(axis=1)
    low = np.flatnonzero(brightest < floor_dn)  # a black level of 0: nothing lies below it
    dead = low[bayer_dn[low].min(axis=1) == brightest[low]] if low.size else low
    if dead.size >= FILLED_ROWS:
        raise InputError(f"{meta.path}: damaged: {dead.size} of its rows (the first at row {dead[0]}) hold one value "
                         f"below half its black level of {meta.black_level_tile().min():g} DN in every sample "
                         "(zero-filled data); copy it from the card again")


def _check_black_below_data(meta: RawMetadata, bayer_dn: np.ndarray) -> None:
    """InputError when a CFA position's median lies more than BLACK_ABOVE_DATA_TOLERANCE of the black-to-white
    range below its black level: noise leaves half the samples of any frame, a dark one included, at or above
    black (ISO 25600-204800 checked), so the file's black level is above its data (black-subtracted data that
    kept its BlackLevel tag) and every sample would be clamped to black."""
    black_tile = meta.black_level_tile()
    range_dn = meta.white_level_dn - float(black_tile.max())
    if not range_dn > 0:  # levels that leave no range are refused where the clip level is known
        return
    for row in range(2):
        for column in range(2):
            samples = bayer_dn[row::2, column::2][::BLACK_CHECK_STRIDE, ::BLACK_CHECK_STRIDE]
            median_dn = float(np.median(samples))
            if median_dn < black_tile[row, column] - BLACK_ABOVE_DATA_TOLERANCE * range_dn:
                raise InputError(f"{meta.path}: half of its samples lie more than "
                                 f"{100 * BLACK_ABOVE_DATA_TOLERANCE:g} % of white below its black level "
                                 f"({black_tile[row, column]:g} DN; median {median_dn:g} DN): the file's black level "
                                 "is above its data - check how it was made")


def sensor_fingerprint(meta: RawMetadata) -> tuple[tuple[str, str], ...]:
    """What tells two camera bodies apart where a file names neither make nor model (CR3, RAF, CRW, MRW, ... are
    not TIFF, and rawpy does not pass LibRaw's make and model on): (property, value) pairs every exposure of one
    body shares, LibRaw's raw size and white level (not the black level: some bodies measure it from each
    frame's masked border); none for a file that names its camera."""
    if meta.camera_model != UNKNOWN_CAMERA:
        return ()
    width, height = meta.raw_size_px
    return ("raw sensor size", f"{width} x {height} px"), ("white level", f"{meta.white_level_dn:g} DN")


def bit_depth_class(white_level_dn: float) -> int:
    """The bit depth a white level belongs to (4095 -> 12, 15000 and 16383 -> 14, 65535 -> 16): frames of one
    body recorded at 12 and 14 bits cannot be merged on one scale."""
    return int(round(float(np.log2(max(white_level_dn, 1.0) + 1.0))))


def warn_shading_not_applied(frames: list[RawFrame]) -> None:
    """One warning for the frames whose DNG lens-shading opcodes are left out (call it after decoding: while
    LibRaw decodes on another thread, its silenced stderr would swallow the line)."""
    shaded = [frame.metadata for frame in frames if frame.metadata.shading_not_applied]
    if shaded:
        warnings.warn(f"{', '.join(meta.path.name for meta in shaded)}: {', '.join(shaded[0].shading_not_applied)} "
                      "not applied (LibRaw leaves DNG opcodes out): the lens's vignetting and colour shading stay "
                      "in the data")


def _read(path: Path, with_pixels: bool) -> tuple[RawMetadata, np.ndarray | None]:
    import rawpy

    if not path.is_file():
        raise InputError(f"{path}: a folder, not a RAW file (ingest groups a folder's RAW files into brackets)"
                         if path.is_dir() else f"{path}: no such RAW file")
    tiff = _tiff_facts(path)
    if tiff.data_end_bytes > tiff.file_bytes:
        raise InputError(f"{path}: truncated or damaged: its image data runs to byte {tiff.data_end_bytes} but the "
                         f"file ends at {tiff.file_bytes}; copy it from the card again")
    if tiff.greyscale_image:  # before LibRaw, which decodes it as RGGB data or fails with a data error
        raise NotRawError(f"{path}: a greyscale TIFF image (one sample a pixel, no CFA or DNG tags: a raw developer's "
                          "black-and-white export?), not a RAW file")
    if tiff.file_bytes < LIBRAW_HEADER_BYTES:  # LibRaw reports an I/O error for these, as for a damaged file
        raise NotRawError(f"{path}: LibRaw does not open it as RAW (only {tiff.file_bytes} bytes: no RAW header)")
    if _is_phase_one(path):
        raise InputError(f"{path}: a Phase One IIQ file (Phase One, Leaf or Mamiya back): LibRaw subtracts its black "
                         "level (per row and column) and applies its sensor corrections only when it develops the "
                         "file, not in the undeveloped data hdrcam reads; convert it to DNG first")
    raw, bayer = rawpy.RawPy(), None
    try:
        with c_stderr_silenced(), _libraw_path(path) as libraw_path:
            raw.open_file(libraw_path)  # the header only: sizes are checked before LibRaw allocates the pixels
            check_image_size(str(path), int(raw.sizes.raw_height), int(raw.sizes.raw_width), RAW_BYTES_PER_PIXEL,
                             "use a machine with more memory")
            try:
                raw.unpack()
            except rawpy.LibRawIOError as error:  # a decoder that reached the end of the file
                raise InputError(f"{path}: truncated or damaged: LibRaw reports an I/O error decoding it "
                                 f"({_libraw_reason(error)}); copy it from the card again") from None
            _check_bayer(path, raw, tiff)
            tile = _visible_tile(raw)
            black = tiff.dng_black_tile or tuple(float(raw.black_level_per_channel[i]) for i in tile)
            _check_black_placement(path, black, tiff)
            other = raw.other
            if with_pixels:  # a read-only view of LibRaw's buffer, which it keeps alive (no copy)
                bayer = raw.raw_image_visible
                bayer.flags.writeable = False
            matrix, matrix_source = _colour_matrix(np.array(raw.rgb_xyz_matrix[:3, :3], dtype=np.float64), tiff)
            neutral, white_balance_source = _as_shot_neutral(np.array(raw.camera_whitebalance[:3], np.float64),
                                                             tiff, matrix, matrix_source)
            metadata = RawMetadata(
                path=path, width_px=int(raw.sizes.width), height_px=int(raw.sizes.height),
                raw_size_px=(int(raw.sizes.raw_width), int(raw.sizes.raw_height)),
                cfa_pattern="".join(_CFA_LETTERS[i] for i in tile),
                black_level_dn=black, white_level_dn=float(raw.white_level),
                xyz_to_camera=matrix, as_shot_neutral=neutral, white_balance_source=white_balance_source,
                exposure_s=float(f"{other.shutter_speed:.7g}"),  # LibRaw keeps float32
                iso=float(other.iso_speed) if other.iso_speed > 0 else tiff.iso,
                f_number=float(f"{other.aperture:.4g}") if other.aperture > 0 else None,  # float32 in LibRaw
                timestamp=other.timestamp if isinstance(other.timestamp, dt.datetime) and
                other.timestamp.year > EPOCH_YEAR else None,  # LibRaw's 0 for a file without a capture time
                camera_model=_camera_name(tiff.make, tiff.model),
                make=tiff.make or UNKNOWN_CAMERA, file_format=tiff.file_format or path.suffix.lstrip(".").upper(),
                colour_matrix_source=matrix_source, shading_not_applied=tiff.shading_opcodes,
                orientation=_exif_orientation(int(raw.sizes.flip)))
    except InputError:
        raise
    except (rawpy.LibRawUnsufficientMemoryError, rawpy.LibRawMemPoolOverflowError) as error:
        raise MemoryError(f"LibRaw decoding {path.name}: {_libraw_reason(error)}") from None
    except rawpy.LibRawFileUnsupportedError as error:
        raise NotRawError(f"{path}: LibRaw does not open it as RAW ({_libraw_reason(error)})") from None
    except Exception as error:  # LibRaw raises many types for damaged files
        raise InputError(f"{path}: cannot read as RAW ({type(error).__name__}: {_libraw_reason(error)})") from None
    finally:
        if bayer is None:
            raw.close()
    filled_rows = repeated_tail_rows(bayer) if bayer is not None and not tiff.data_end_checked else 0
    if filled_rows >= FILLED_ROWS:
        raise InputError(f"{path}: truncated or damaged: its last {filled_rows} rows repeat one row (LibRaw fills "
                         "what a file lacks that way); copy it from the card again")
    if not metadata.exposure_s > 0:
        raise InputError(f"{path}: the file records no exposure time (EXIF ExposureTime), which merging needs; "
                         "use the camera's original file")
    return metadata, bayer


PHASE_ONE_SEARCH_BYTES = 32  # LibRaw's identify() looks for "MMMM", then "IIII", in a file's first 32 bytes
PHASE_ONE_MAGIC = {b"MMMM": (4, b"Raw"), b"IIII": (5, b"waR")}  # then "RawI" in that byte order 4 bytes on


def _is_phase_one(path: Path) -> bool:
    """Whether LibRaw takes the file for a Phase One IIQ: a byte-order mark in its first PHASE_ONE_SEARCH_BYTES
    followed by the format's magic (parse_phase_one returns at once without it, and the file goes on as TIFF).
    Its compressed IIQ decoders leave the data undeveloped: LibRaw reports a black level of 0 (LibRaw/LibRaw#432:
    IQ180 data bottoming out at 238 DN) and subtracts the back's black level, per row and column, and applies its
    sensor corrections in raw2image_ex (phase_one_subtract_black, phase_one_correct), which rawpy's raw_image
    never passes through."""
    with open(path, "rb") as file:
        head = file.read(PHASE_ONE_SEARCH_BYTES + 8)
    for mark, (offset, magic) in PHASE_ONE_MAGIC.items():
        at = head.find(mark, 0, PHASE_ONE_SEARCH_BYTES)
        if at >= 0:
            return head[at + offset:at + offset + 3] == magic
    return False


@contextlib.contextmanager
def _libraw_path(path: Path):
    """A name LibRaw can open for ``path``: rawpy encodes names as UTF-8, so a name that is not (Latin-1 bytes
    from a card, kept by Python as surrogate escapes) is opened by its descriptor's name, /dev/fd/N."""
    try:
        str(path).encode("utf-8")
    except UnicodeEncodeError:
        pass  # not inside the handler: the body's own exceptions would chain to this one
    else:
        yield str(path)
        return
    descriptor = os.open(path, os.O_RDONLY)
    try:
        yield f"/dev/fd/{descriptor}"
    finally:
        os.close(descriptor)


def repeated_tail_rows(bayer_dn: np.ndarray) -> int:
    """How many rows at the bottom repeat the one above them bit for bit (0 when the last row is flat: a clipped
    or black row may legitimately repeat)."""
    if bayer_dn.shape[0] < 2 or bayer_dn[-1].min() == bayer_dn[-1].max():
        return 0
    differs = np.flatnonzero(np.any(bayer_dn[1:] != bayer_dn[:-1], axis=1))
    return bayer_dn.shape[0] - 1 - (int(differs[-1]) + 1 if differs.size else 0)


def _libraw_reason(error: Exception) -> str:
    """rawpy's message without the bytes literal around LibRaw's text."""
    text = str(error)
    return text[2:-1] if text[:2] in ("b'", 'b"') and text[-1:] in ("'", '"') else text


def _exif_orientation(libraw_flip: int) -> int:
    """The EXIF Orientation code (1 to 8) of LibRaw's ``sizes.flip``: 0 -> 1 (upright), 3 -> 3 (turn 180 degrees to
    display), 5 -> 8 (turn 90 degrees anticlockwise), 6 -> 6 (turn 90 degrees clockwise), and the mirrored ones
    1 -> 2, 2 -> 4, 4 -> 5, 7 -> 7; 1 for anything else.

    flip is dcraw's bit field (4 transpose, 2 mirror top to bottom, 1 mirror left to right). LibRaw reads the
    EXIF tag as ``"50132467"[orientation & 7]`` (src/metadata/tiff.cpp, tag 0x0112) and turns a flip given in
    degrees into 6 (90), 3 (180) or 5 (270) when it opens a file (src/metadata/identify.cpp); this is the inverse
    of that string, checked with DNGs of each Orientation 1 to 8 against LibRaw's own rendering
    (tests/io/test_orientation.py)."""
    return _EXIF_ORIENTATION.get(libraw_flip, 1)


def _check_bayer(path: Path, raw, tiff: "_TiffFacts") -> None:
    """InputError unless the sensor is a 2 x 2 Bayer mosaic of R, G, B on a square grid. A DNG's own CFA tags name
    its pattern before LibRaw's does (LibRaw takes any 6 x 6 pattern for X-Trans and cannot hold a 4 x 4 one)."""
    import rawpy

    if tiff.cfa_layout not in (None, 1):
        raise InputError(f"{path}: staggered CFA layout (CFALayout {tiff.cfa_layout}: rows or columns offset by half "
                         "a pixel) is not supported; hdrcam merges 2 x 2 Bayer data on a square grid only")
    if raw.raw_type != rawpy.RawType.Flat:
        raise InputError(f"{path}: not a mosaic RAW (LibRaw: {raw.raw_type.name}, e.g. a Foveon or linear DNG); "
                         "hdrcam merges 2 x 2 Bayer data only")
    sizes = raw.sizes
    if raw.raw_image_visible.shape != (sizes.height, sizes.width):
        raise InputError(f"{path}: LibRaw's visible area ({sizes.width} x {sizes.height} px from column "
                         f"{sizes.left_margin}, row {sizes.top_margin}) does not fit in its raw data "
                         f"({sizes.raw_width} x {sizes.raw_height} px), e.g. a staggered sensor layout; hdrcam "
                         "merges 2 x 2 Bayer data on a square grid only")
    pattern = np.asarray(raw.raw_pattern)
    if raw.num_colors == 1 or pattern.size == 1:
        raise InputError(f"{path}: monochrome sensor (no colour filter array); hdrcam merges 2 x 2 Bayer data only")
    if tiff.cfa_repeat_dim not in (None, (2, 2)):
        rows, columns = tiff.cfa_repeat_dim
        name = _cfa_name(np.resize(tiff.cfa_codes, (rows, columns)))
        raise InputError(f"{path}: {rows} x {columns} {name + ' ' if name else ''}CFA is not supported: "
                         "hdrcam merges 2 x 2 Bayer data only")
    if pattern.shape == (6, 6):
        raise InputError(f"{path}: X-Trans sensor (6 x 6 colour filter); hdrcam merges 2 x 2 Bayer data only")
    if raw.num_colors != 3 or pattern.shape != (2, 2) or sorted({_CFA_LETTERS[i] for i in pattern.ravel()}) != \
            ["B", "G", "R"]:
        raise InputError(f"{path}: colour filter {raw.color_desc.decode(errors='replace')} of "
                         f"{pattern.shape[0]} x {pattern.shape[1]} is not a 2 x 2 RGB Bayer mosaic; hdrcam merges "
                         "those only")
    tile = "".join(_CFA_LETTERS[i] for i in pattern.ravel())
    if tile not in BAYER_TILES:  # R, G and B, but not each green diagonal to the other (RGBG, RRGB, ...)
        raise InputError(f"{path}: colour filter tile {tile} is not a Bayer layout ({', '.join(BAYER_TILES)}); "
                         "hdrcam merges those only")


BAYER_TILES = ("RGGB", "BGGR", "GRBG", "GBRG")


def _visible_tile(raw) -> np.ndarray:
    """LibRaw's colour indices (0 R, 1 G, 2 B, 3 second G) of the 2 x 2 tile whose top-left is the first visible
    pixel, row-major. rawpy's ``raw_pattern`` is laid out from the raw data's origin, margins included (rawpy's
    ``raw_color`` takes full-RAW coordinates and ``raw_colors_visible`` crops that layout at the margins), so an odd
    top or left margin shifts the tile by a row or column. LibRaw evens such margins when it opens a Bayer file
    (src/utils/open.cpp); the tile does not depend on it."""
    sizes = raw.sizes
    pattern = np.roll(np.asarray(raw.raw_pattern), (-int(sizes.top_margin), -int(sizes.left_margin)), axis=(0, 1))
    return pattern[:2, :2].ravel()


def _check_black_placement(path: Path, black_dn: tuple[float, ...], tiff: "_TiffFacts") -> None:
    """InputError for a DNG whose ActiveArea starts on an odd row or column and whose black level differs by
    colour site: LibRaw then rounds the margin to an even one and places the sites' black levels on the wrong
    sites (fused radiance 20x off on some, negative on others: measured), and hdrcam takes its levels."""
    if any(origin % 2 for origin in tiff.active_area_origin) and max(black_dn) - min(black_dn) > 0.5:
        raise InputError(f"{path}: its ActiveArea starts at row {tiff.active_area_origin[0]}, column "
                         f"{tiff.active_area_origin[1]} (odd) and its black level differs by colour site "
                         f"({', '.join(f'{b:g}' for b in black_dn)} DN): LibRaw places such levels on the wrong "
                         "sites, so hdrcam cannot subtract them; convert the file with one black level, or crop "
                         "its ActiveArea to an even origin")


def _cfa_name(codes: np.ndarray) -> str:
    """What a DNG's rows x columns CFA pattern (colour codes, 0 R, 1 G, 2 B) is called: "Quad-Bayer" or
    "Nona-Bayer" when each colour of a 2 x 2 tile covers 2 x 2 or 3 x 3 pixels, "X-Trans" for a 6 x 6 pattern with
    red, green and blue in every row and column, else ""."""
    rows, columns = codes.shape
    block = rows // 2
    if rows == columns and block in _BLOCK_BAYER_NAMES and \
            np.array_equal(codes, codes[::block, ::block].repeat(block, 0).repeat(block, 1)):
        return _BLOCK_BAYER_NAMES[block]
    if codes.shape == (6, 6) and all({0, 1, 2} <= set(line.tolist()) for line in (*codes, *codes.T)):
        return "X-Trans"
    return ""


def _colour_matrix(libraw_matrix: np.ndarray, tiff: "_TiffFacts") -> tuple[np.ndarray, str]:
    """(XYZ -> camera matrix, where it came from): LibRaw's, else the DNG tags', else the identity."""
    candidates = [(f"DNG {name}", matrix) for name, matrix in tiff.colour_matrices] + [("LibRaw", libraw_matrix)]
    for source, matrix in candidates:
        if _usable(matrix):
            return matrix, source
    return np.eye(3), NO_COLOUR_MATRIX


def _usable(matrix: np.ndarray | None) -> bool:
    return matrix is not None and matrix.shape == (3, 3) and bool(np.isfinite(matrix).all()) \
        and abs(float(np.linalg.det(matrix))) > _MIN_MATRIX_DETERMINANT


_reading_tiff_facts = threading.local()  # set while this thread's tifffile reads a RAW file's structure


class _QuietWhileReadingRaw(logging.Filter):
    """Drops tifffile's log records emitted while hdrcam reads a RAW file's TIFF structure: tifffile warns on
    stderr about formats it cannot decode (ORF, RW2: "RAW format 0x4F52 not supported"), which LibRaw reads."""

    def filter(self, record: logging.LogRecord) -> bool:
        return not getattr(_reading_tiff_facts, "active", False)


logging.getLogger("tifffile").addFilter(_QuietWhileReadingRaw())


@dataclasses.dataclass
class _TiffFacts:
    """What the TIFF structure of a RAW file says (nothing for formats that are not TIFF: CR3, RAF, CRW...)."""

    file_bytes: int
    data_end_bytes: int = 0  # the furthest byte any image strip or tile of any IFD needs
    data_end_checked: bool = False  # every strip's and tile's end known: data_end_bytes alone shows a truncation
    make: str | None = None
    model: str | None = None
    iso: float | None = None
    file_format: str | None = None  # "DNG" when the DNGVersion tag is there
    colour_matrices: list = dataclasses.field(default_factory=list)  # [(tag name, 3 x 3)], preferred first
    as_shot_white_xy: tuple[float, float] | None = None  # DNG AsShotWhiteXY, when the file has it
    shading_opcodes: tuple[str, ...] = ()  # DNG lens-shading opcodes of the raw image (hdrcam.io.dng_opcodes)
    cfa_repeat_dim: tuple[int, int] | None = None  # a DNG raw image's CFARepeatPatternDim (rows, columns)
    cfa_codes: tuple[int, ...] = ()  # its CFAPattern, row-major (0 R, 1 G, 2 B, ...)
    cfa_layout: int | None = None  # its CFALayout (1: a square grid; 2 to 9: staggered)
    active_area_origin: tuple[int, int] = (0, 0)  # its ActiveArea's top row and left column
    greyscale_image: bool = False  # an image, not RAW: :func:`_is_greyscale_image`
    dng_black_tile: tuple[float, float, float, float] | None = None  # a DNG's BlackLevel tags per 2 x 2 position


def _tiff_facts(path: Path) -> _TiffFacts:
    facts = _TiffFacts(file_bytes=path.stat().st_size)
    _reading_tiff_facts.active = True
    try:
        with tifffile.TiffFile(path) as tiff:
            tags = tiff.pages[0].tags
            facts.make, facts.model = (_text(tags, code) for code in (271, 272))
            exif = tags[34665].value if 34665 in tags else {}
            iso_value = tags[34855].value if 34855 in tags else (exif or {}).get("ISOSpeedRatings")
            if isinstance(iso_value, (tuple, list)):
                iso_value = iso_value[0] if iso_value else None
            facts.iso = float(iso_value) if iso_value else None
            if 50706 in tags:
                facts.file_format = "DNG"
            matrices = [(name, _dng_transform(tags, code, calibration),
                         tags[illuminant].value if illuminant in tags else 0)
                        for name, code, illuminant, calibration in (("ColorMatrix2", 50722, 50779, 50724),
                                                                    ("ColorMatrix1", 50721, 50778, 50723))
                        if code in tags and len(np.ravel(tags[code].value)) >= 9]
            matrices.sort(key=lambda entry: entry[2] != _D65)  # stable: D65 first, then ColorMatrix2, 1
            facts.colour_matrices = [(name, matrix) for name, matrix, _ in matrices]
            white_xy = _tag_values(tags[50729], 2) if 50729 in tags else None
            if white_xy is not None and np.all(np.isfinite(white_xy)) and white_xy[1] > 0:
                facts.as_shot_white_xy = (float(white_xy[0]), float(white_xy[1]))
            pages = list(_all_pages(tiff))
            facts.greyscale_image = facts.file_format != "DNG" and _is_greyscale_image(pages, facts.make or "")
            ends = [_data_end(page) for page in pages]
            facts.data_end_bytes = max((end for end, _ in ends), default=0)
            facts.data_end_checked = facts.data_end_bytes > 0 and all(trusted for _, trusted in ends)
            if facts.file_format == "DNG":
                full_resolution = [page for page in pages if is_full_resolution_image(page)]  # not previews
                facts.shading_opcodes = tuple(dict.fromkeys(name for page in full_resolution
                                                            for name in shading_opcodes(page.tags)))
                mosaic = next((page.tags for page in full_resolution if page.photometric == 32803), {})  # CFA
                if 33421 in mosaic and 33422 in mosaic:
                    facts.cfa_repeat_dim = tuple(int(n) for n in mosaic[33421].value)
                    facts.cfa_codes = tuple(mosaic[33422].value)
                facts.cfa_layout = int(mosaic[50711].value) if 50711 in mosaic else None
                if 50829 in mosaic:  # ActiveArea: top, left, bottom, right
                    facts.active_area_origin = tuple(int(n) for n in tuple(mosaic[50829].value)[:2])
                if any(code in mosaic for code in (50714, 50715, 50716)):
                    tile = _dng_black_tile(mosaic)
                    facts.dng_black_tile = tile if all(np.isfinite(tile)) else None  # a zero denominator: LibRaw's
    except Exception:  # not a TIFF, or a TIFF whose structure tifffile cannot follow: LibRaw decides
        pass
    finally:
        _reading_tiff_facts.active = False
    return facts


_GREYSCALE_PHOTOMETRIC = (0, 1)  # TIFF 6.0 PhotometricInterpretation WhiteIsZero, BlackIsZero
_CFA_TAGS = (33421, 33422)  # TIFF/EP CFARepeatPatternDim, CFAPattern (not EXIF's CFAPattern, which exports copy)


def _is_greyscale_image(pages: list, make: str) -> bool:
    """True for a TIFF whose every image (IFD0, SubIFDs and others) has one sample a pixel, a greyscale
    PhotometricInterpretation and no TIFF/EP CFA tags: a raw developer's 16-bit black-and-white export, which
    LibRaw decodes as mosaic data with a default RGGB pattern, or fails on with a data error (LibRaw's apply_tiff,
    src/metadata/tiff.cpp, turns such TIFFs away at 8 bits only). Not for the makes apply_tiff accepts them from
    at 8 bits too (make starting "Phase" or "Leaf", or containing "Kodak": backs that store their mosaic so)."""
    if not pages or make.startswith(("Phase", "Leaf")) or "kodak" in make.lower():
        return False
    return all(262 in page.tags and page.tags[262].value in _GREYSCALE_PHOTOMETRIC and page.samplesperpixel == 1
               and not any(code in page.tags for code in _CFA_TAGS) for page in pages)


def _dng_black_tile(tags) -> tuple[float, float, float, float]:
    """The black level (DN, float) of each position of the 2 x 2 tile from a DNG raw image's tags (DNG spec 1.4,
    chapter 6): a sample at row r, column c of the ActiveArea has BlackLevel[r % R][c % C] (R x C from
    BlackLevelRepeatDim, default 1 x 1 - a square count without it is taken as that square, as dcraw does;
    BlackLevel default 0; SHORT, LONG or RATIONAL, read by the tag's type) + BlackLevelDeltaH[c] +
    BlackLevelDeltaV[r] (SRATIONAL, one per column and row). Per position, the mean over its rows and columns:
    the tile holds one level per position (a repeat of 1 or 2 and constant deltas, as converters write, are
    exact). The tile starts at the ActiveArea's origin, where LibRaw's visible area starts (an odd origin is
    refused when the positions differ: :func:`_check_black_placement`). NaN where a rational's denominator is 0."""
    stored = _tag_numbers(tags[50714]) if 50714 in tags and tags[50714].count else np.zeros(1)
    side = math.isqrt(stored.size)
    rows, columns = (int(n) for n in tags[50713].value) if 50713 in tags else \
        ((side, side) if side * side == stored.size else (1, 1))
    levels = np.resize(stored, rows * columns).reshape(rows, columns)  # a short list repeats (a damaged tag)
    repeated = np.tile(levels, (2, 2))  # 2R x 2C: a whole number of both the repeat and the 2 x 2 tile
    tile = np.array([[repeated[row::2, column::2].mean() for column in range(2)] for row in range(2)])
    for code, axis in ((50716, 0), (50715, 1)):  # DeltaV per row, DeltaH per column
        if code in tags:
            deltas = _tag_numbers(tags[code])
            means = [float(np.mean(deltas[phase::2])) if deltas[phase::2].size else 0.0 for phase in range(2)]
            tile += np.array(means)[:, None] if axis == 0 else np.array(means)[None, :]
    return tuple(float(b) for b in tile.ravel())


def _camera_name(make: str | None, model: str | None) -> str:
    """Make and model as one name; the model alone where it starts with the make's first word (Canon, Nikon and
    Pentax models do: "Canon Canon EOS 5D Mark III" was the name)."""
    if make and model and model.split()[0].lower() == make.split()[0].lower():
        return model
    return " ".join(part for part in (make, model) if part) or UNKNOWN_CAMERA


def _text(tags, code: int) -> str | None:
    if code not in tags:
        return None
    value = tags[code].value
    text = value.decode(errors="replace") if isinstance(value, bytes) else str(value)
    return text.strip("\x00 ").strip() or None


RATIONAL, SRATIONAL = 5, 10  # TIFF 6.0 field types


def _tag_numbers(tag) -> np.ndarray:
    """A numeric TIFF tag's values as floats, read by its type: (S)RATIONAL numerator / denominator pairs divided
    (NaN where a denominator is 0), the integer and float types as stored (a SHORT BlackLevel of 512, 512 is not
    the ratio 1)."""
    flat = np.asarray(tag.value, dtype=np.float64).ravel()
    if int(tag.dtype) not in (RATIONAL, SRATIONAL):  # tifffile: the field type
        return flat
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(flat[1::2] != 0, flat[0::2] / flat[1::2], np.nan)


def _tag_values(tag, count: int) -> np.ndarray:
    """``count`` floats of a numeric TIFF tag (:func:`_tag_numbers`), NaN where a value is missing."""
    values = _tag_numbers(tag)[:count]
    return np.concatenate([values, np.full(count - values.size, np.nan)])


def _dng_transform(tags, matrix_code: int, calibration_code: int) -> np.ndarray:
    """The DNG model's XYZ -> camera matrix for one calibration illuminant: AnalogBalance x CameraCalibration x
    ColorMatrix; the calibration only when the CameraCalibrationSignature (50931) equals the
    ProfileCalibrationSignature (50932), both absent included."""
    matrix = _tag_values(tags[matrix_code], 9).reshape(3, 3)
    if calibration_code in tags and _text(tags, 50931) == _text(tags, 50932):
        calibration = _tag_values(tags[calibration_code], 9).reshape(3, 3)
        if np.all(np.isfinite(calibration)):
            matrix = calibration @ matrix
    if 50727 in tags:
        balance = _tag_values(tags[50727], 3)
        if np.all(np.isfinite(balance)) and np.all(balance > 0):
            matrix = np.diag(balance) @ matrix
    return matrix


def _all_pages(tiff: tifffile.TiffFile):
    """Every IFD, SubIFDs included (an ARW's or DNG's RAW data often lives in a SubIFD)."""
    stack = list(tiff.pages)
    while stack:
        page = stack.pop()
        yield page
        stack.extend(getattr(page, "pages", None) or [])


def _data_end(page) -> tuple[int, bool]:
    """(the furthest byte the page's strips or tiles need, whether every byte count was believed).

    An uncompressed strip needs its rows' bytes (at most two bytes a sample: 12- and 14-bit data may be stored
    unpacked) even where its count says more; a compressed one whose count is at least its uncompressed size is
    not believed (older Hasselblad 3FRs declare the uncompressed size for compressed data, past the end of the
    file), only its start counts. Counts are believed where the page does not give its size."""
    offsets, counts = getattr(page, "dataoffsets", ()), getattr(page, "databytecounts", ())
    ends, believed = [0], True
    for offset, count, (packed, unpacked) in zip(offsets, counts, _uncompressed_bytes(page)):
        if not count:
            continue
        if page.compression == 1:
            count = min(count, unpacked)
        elif count >= packed:
            count, believed = 0, False
        ends.append(int(offset) + int(count))
    return max(ends), believed


def _uncompressed_bytes(page) -> list[tuple[float, float]]:
    """Each strip's or tile's size uncompressed, in bytes, packed (BitsPerSample bits a sample) and unpacked (whole
    bytes a sample); inf where the page does not give its size (a JPEG preview whose header tifffile could not
    read, samples of different depths). A tile is whole even past the image's edge; a strip holds RowsPerStrip
    rows, the last one of a plane the rows left."""
    chunks, bits, length = len(page.dataoffsets), page.bitspersample, page.imagelength
    if not isinstance(bits, int) or not bits or not length or not page.imagewidth:
        return [(math.inf, math.inf)] * chunks
    if page.is_tiled:
        samples = [math.prod(page.chunks)] * chunks
    else:
        rows, row_samples = min(page.rowsperstrip, length), math.prod(page.chunks[1:])
        if not rows:  # RowsPerStrip 0 (invalid): the counts are believed
            return [(math.inf, math.inf)] * chunks
        strips = math.ceil(length / rows)
        samples = [min(rows, length - index % strips * rows) * row_samples for index in range(chunks)]
    return [(n * bits // 8, n * math.ceil(bits / 8)) for n in samples]


def _as_shot_neutral(multipliers: np.ndarray, tiff: _TiffFacts, xyz_to_camera: np.ndarray, source: str
                     ) -> tuple[np.ndarray, str]:
    """(camera RGB of white, max 1; its ``white_balance_source``): LibRaw's as-shot white balance (the reciprocals
    of its multipliers), else a DNG's AsShotWhiteXY through any usable matrix, else D65 through it
    (module docstring), else ones."""
    if np.all(multipliers > 0):
        neutral = 1.0 / multipliers
        return neutral / neutral.max(), AS_SHOT
    if tiff.as_shot_white_xy and source != NO_COLOUR_MATRIX:  # the DNG's matrix or LibRaw's table for the model
        neutral = _neutral_of_white(tiff.as_shot_white_xy, xyz_to_camera)
        if neutral is not None:
            return neutral, AS_SHOT
    daylight = _neutral_of_white(_D65_XY, xyz_to_camera) if source != NO_COLOUR_MATRIX else None
    return (np.ones(3), NO_WHITE_BALANCE) if daylight is None else (daylight, DAYLIGHT_ASSUMED)


def _neutral_of_white(white_xy: tuple[float, float], xyz_to_camera: np.ndarray) -> np.ndarray | None:
    """Camera RGB (max 1) of the white of chromaticity ``white_xy`` (CIE 1931 x, y; Y = 1), or None when a channel
    is not positive."""
    x, y = white_xy
    neutral = xyz_to_camera @ np.array([x / y, 1.0, (1.0 - x - y) / y])
    return neutral / neutral.max() if np.all(neutral > 0) else None
