"""OpenEXR read and write (linear float images, any channel set, metadata attributes).

Reading returns float32 channels at full resolution over the display window (the image's frame; the data window
is the pixels stored): pixels stored beyond the frame (overscan) are dropped, pixels of the frame the file does not
store are 0. A file whose colour is in a named layer only ("beauty.R", Blender's "ViewLayer.Combined.R") is
read from that layer (_with_image_layer_as_rgb). Luminance-chroma files (Y, RY, BY, as written by
OpenEXR's RgbaYca interface, chroma subsampled 2x2) are converted to RGB with the file's chromaticities
(Rec. 709 / D65 when absent). R, G, B come back in Rec. 709 primaries with a D65 white (linear sRGB, what
hdrcam's scenes and frames are): a file whose ``chromaticities`` attribute names other primaries (ACES AP0,
Rec. 2020, ...) is converted with Bradford adaptation between the white points (hdrcam.colorimetry; the
attribute then no longer describes the pixels and is dropped), unless the caller keeps the stored primaries
(a captured frame: hdrcam.io.ldr_frame); primaries that span no gamut (all zero, as some
writers store) count as absent. Damaged files raise :class:`~hdrcam.errors.InputError` with
one line.

Writing is atomic, float32 by default or half on request, ZIP-compressed by default or uncompressed on
request (both are part of every OpenEXR version); half output refuses values beyond the half range (65504)
instead of silently storing Inf.
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
import threading
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import OpenEXR

from hdrcam.colorimetry import REC709_CHROMATICITIES, in_rec709, normalised_primary_matrix, to_rec709_matrix
from hdrcam.errors import InputError, escaped_name, not_a_file_reason
from hdrcam.io.atomic import atomic_path
from hdrcam.io.c_stderr import c_stderr_silenced
from hdrcam.io.file_magic import EXR_MAGIC, not_format_reason, starts_with
from hdrcam.limits import check_image_size, check_memory
from hdrcam.parallel import worker_threads

HALF_MAX = float(np.finfo(np.float16).max)  # 65504
DECODED_BYTES_PER_SAMPLE = 12  # the decoded float32 plane, its full-resolution copy and one working copy
# Header keys that OpenEXR manages itself; everything else is a user attribute.
_STRUCTURAL_KEYS = {
    "channels", "compression", "dataWindow", "displayWindow", "lineOrder", "pixelAspectRatio",
    "screenWindowCenter", "screenWindowWidth", "tiles", "type", "preview", "name", "version",
    "chunkCount",
}


@dataclasses.dataclass
class ExrImage:
    """Channels of one EXR part (float32, H x W each) and its user attributes."""

    channels: dict[str, np.ndarray]
    attributes: dict[str, Any]
    source: Path | None = None  # the file read, named in errors

    @property
    def shape(self) -> tuple[int, int]:
        return next(iter(self.channels.values())).shape

    def rgb(self) -> np.ndarray:
        """H x W x 3 float32 linear RGB; raises InputError when the file has no colour channels."""
        if all(name in self.channels for name in "RGB"):
            return np.stack([self.channels[name] for name in "RGB"], axis=-1)
        raise InputError(f"{self.source or 'EXR'}: has channels {sorted(self.channels)}, not R, G, B")

    def single(self) -> np.ndarray:
        """H x W float32 of a single-channel file (e.g. a height map)."""
        if len(self.channels) != 1:
            raise InputError(f"{self.source or 'EXR'}: expected a single-channel EXR, found channels "
                             f"{sorted(self.channels)}")
        return next(iter(self.channels.values()))


def exr_orientation(attributes: dict[str, Any]) -> int:
    """The EXIF Orientation code (1 to 8) an EXR's ``orientation`` attribute gives its pixels (hdrcam writes one
    on images kept in a sensor's orientation), 1 for none or another value."""
    value = attributes.get("orientation")
    return value if isinstance(value, int) and not isinstance(value, bool) and 1 <= value <= 8 else 1


_UNREADABLE = (RuntimeError, UnicodeDecodeError, ValueError, TypeError, OSError, MemoryError)  # OpenEXR's raises


def read_exr_attributes(path: Path) -> dict[str, Any]:
    """An EXR's user attributes, from its header alone. InputError for a missing or damaged file."""
    try:
        return _user_attributes(_header(Path(path).read_bytes()))
    except _UNREADABLE as error:
        raise _unreadable(path, error) from None


LOSSY_COMPRESSIONS = {OpenEXR.DWAA_COMPRESSION: "DWAA", OpenEXR.DWAB_COMPRESSION: "DWAB"}  # lossy on every type
HALF_LOSSY_COMPRESSIONS = {OpenEXR.B44_COMPRESSION: "B44", OpenEXR.B44A_COMPRESSION: "B44A"}  # lossy on half
# channels only (float32 ones are stored as they are); PXR24 rounds float32 to 24 bits, 1e-5: no ringing


def lossy_compression(path: Path) -> str | None:
    """The name of the compression of an EXR's image part where it altered the colour channels' values: DWAA or
    DWAB, or B44 / B44A on half-float colour channels; None for a lossless file, or one that cannot be read. The
    file's pixels are read again (the channels' stored types are not in the header OpenEXR's binding gives)."""
    try:
        with _openexr_quiet(), OpenEXR.File(io.BytesIO(Path(path).read_bytes()), separate_channels=True) as file:
            part = _image_part(file.parts)
            compression = part.header.get("compression")
            half = any(channel.pixels.dtype == np.float16 for channel in part.channels.values())
    except _UNREADABLE:
        return None
    return LOSSY_COMPRESSIONS.get(compression) or (HALF_LOSSY_COMPRESSIONS.get(compression) if half else None)


def _header(data: bytes) -> dict[str, Any]:
    return _part_headers(data)[0]


def _part_headers(data: bytes) -> list[dict[str, Any]]:
    """Every part's header (a single-part file has one), without decoding pixels."""
    with _openexr_quiet(), OpenEXR.File(io.BytesIO(data), header_only=True) as header_file:
        return [dict(part.header) for part in header_file.parts] or [dict(header_file.header())]


def _user_attributes(header: dict[str, Any]) -> dict[str, Any]:
    return {key: value for key, value in header.items() if key not in _STRUCTURAL_KEYS}


def _unreadable(path: Path, error: Exception) -> InputError:
    reason = str(error).splitlines()[0] if str(error) else type(error).__name__
    return InputError(f"{path}: not a readable OpenEXR file ({reason[:120]})")


def read_exr(path: Path, *, to_rec709: bool = True) -> ExrImage:
    """Read an EXR file. Raises InputError for a missing, damaged or unsupported file. ``to_rec709`` False keeps
    R, G, B in the file's own primaries (and its ``chromaticities`` attribute): a captured frame, whose clipped
    samples are clipped per stored channel, which a matrix would mix."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: {not_a_file_reason(path, 'an image file')}")
    data = path.read_bytes()  # through Python: any file name works, and OS errors keep their cause
    if not data.startswith(EXR_MAGIC):  # OpenEXR would name its own stream, "<python_buffer>", not the file
        raise InputError(f"{path}: {not_format_reason(path, 'OpenEXR')}")
    try:
        _check_decoded_size(path, _part_headers(data))
        with _openexr_quiet(), OpenEXR.File(io.BytesIO(data), separate_channels=True) as exr_file:
            part = _image_part(exr_file.parts)
            header = dict(part.header)
            raw_channels = {name: (channel.pixels, channel.xSampling, channel.ySampling)
                            for name, channel in part.channels.items()}
    except _UNREADABLE as error:
        raise _unreadable(path, error) from None
    if not raw_channels:
        raise InputError(f"{path}: EXR file has no channels")
    height, width = _window_size(header["dataWindow"])
    channels = {name: _full_resolution(pixels, x_sampling, y_sampling, height, width, path, name)
                for name, (pixels, x_sampling, y_sampling) in raw_channels.items()}
    channels = _with_image_layer_as_rgb(path, channels)
    if {"Y", "RY", "BY"} <= channels.keys() and not {"R", "G", "B"} & channels.keys():
        chromaticities = header.get("chromaticities", REC709_CHROMATICITIES)
        try:
            red, green, blue = _luminance_chroma_to_rgb(channels.pop("Y"), channels.pop("RY"),
                                                        channels.pop("BY"), chromaticities)
        except ValueError as error:
            raise InputError(f"{path}: luminance-chroma file with unusable {error}") from None
        channels = {"R": red, "G": green, "B": blue, **channels}
    display_window = header.get("displayWindow", header["dataWindow"])
    if not _windows_overlap(header["dataWindow"], display_window):
        raise InputError(f"{path}: no stored pixel lies in the image's frame (data window "
                         f"{_shown(header['dataWindow'])}, display window {_shown(display_window)})")
    channels = {name: _in_display_window(plane, header["dataWindow"], display_window)
                for name, plane in channels.items()}
    attributes = _user_attributes(header)
    if to_rec709 and to_rec709_matrix(header.get("chromaticities")) is not None and {"R", "G", "B"} <= channels.keys():
        rgb = in_rec709(np.stack([channels[name] for name in "RGB"], axis=-1), header["chromaticities"])
        channels.update(R=rgb[..., 0].copy(), G=rgb[..., 1].copy(), B=rgb[..., 2].copy())
        attributes.pop("chromaticities", None)
    return ExrImage(channels=channels, attributes=attributes, source=Path(path))



COLOUR_CHANNEL_SETS = ({"R", "G", "B"}, {"Y", "RY", "BY"}, {"Y"})


def _window_size(window) -> tuple[int, int]:
    """(height, width) in pixels of an OpenEXR box ((x min, y min), (x max, y max)), corners inclusive."""
    (x_min, y_min), (x_max, y_max) = window
    return int(y_max) - int(y_min) + 1, int(x_max) - int(x_min) + 1


def _shown(window) -> str:
    """An OpenEXR box as "(x min, y min) - (x max, y max)", in pixels, for messages."""
    (x_min, y_min), (x_max, y_max) = window
    return f"({int(x_min)}, {int(y_min)}) - ({int(x_max)}, {int(y_max)})"


def _windows_overlap(data_window, display_window) -> bool:
    """Whether any pixel of the data window lies in the display window (boxes in pixels, corners inclusive)."""
    (data_x0, data_y0), (data_x1, data_y1) = data_window
    (frame_x0, frame_y0), (frame_x1, frame_y1) = display_window
    return max(data_x0, frame_x0) <= min(data_x1, frame_x1) and max(data_y0, frame_y0) <= min(data_y1, frame_y1)


def _in_display_window(plane: np.ndarray, data_window, display_window) -> np.ndarray:
    """A plane stored over ``data_window`` as the image, the ``display_window`` (OpenEXR's Technical Introduction:
    the display window is the image's boundary, the data window the pixels stored): pixels beyond the frame
    (overscan) dropped, pixels of the frame that are not stored are 0 (no light: the background the OpenEXR
    documentation asks to fill them with). The plane itself when the two windows are the same."""
    (data_x0, data_y0), _ = data_window
    (frame_x0, frame_y0), _ = display_window
    if _window_size(data_window) == _window_size(display_window) and (data_x0, data_y0) == (frame_x0, frame_y0):
        return plane
    height, width = _window_size(display_window)
    framed = np.zeros((height, width), plane.dtype)
    top, left = int(data_y0) - int(frame_y0), int(data_x0) - int(frame_x0)  # the data's corner in the frame
    rows = slice(max(top, 0), min(top + plane.shape[0], height))
    columns = slice(max(left, 0), min(left + plane.shape[1], width))
    framed[rows, columns] = plane[rows.start - top:rows.stop - top, columns.start - left:columns.stop - left]
    return framed


def _image_part(parts):
    """The part of a (multi-part) file that holds the image: the first with colour channels (a renderer may
    store depth or masks first), else the first part (a single-channel file: a height map); ValueError for a
    file whose headers were read but no part decoded (OpenEXR's binding returns none for truncated pixel data)."""
    if not parts:
        raise ValueError("its pixel data cannot be decoded: truncated or damaged")
    return parts[_image_index([set(part.channels) for part in parts])]


def _image_index(channel_names: list[set[str]]) -> int:
    """The index of the image among parts with these channel names (see _image_part); a part whose colour is in
    a named layer only (beauty.R, ...) after those with unprefixed colour channels."""
    for channel_set in COLOUR_CHANNEL_SETS:
        for index, names in enumerate(channel_names):
            if channel_set <= names:
                return index
    return next((index for index, names in enumerate(channel_names) if _image_layer(names) is not None),
                next((index for index, names in enumerate(channel_names) if _rgb_layers(names)), 0))


IMAGE_LAYER_NAMES = ("combined", "beauty", "rgba")  # Blender's render result (ViewLayer.Combined), others' beauty


def _rgb_layers(names) -> list[str]:
    """The layers (OpenEXR's naming: "layer.R"; the prefix with its dot, "" for unprefixed R, G, B) that hold R,
    G and B channels."""
    prefixes = {name[:-1] for name in names if name.endswith(("R", "G", "B")) and (len(name) == 1 or name[-2] == ".")}
    return sorted(prefix for prefix in prefixes if all(prefix + colour in names for colour in "RGB"))


def _image_layer(names) -> str | None:
    """Of the layers holding R, G and B (:func:`_rgb_layers`), the image's: the only one, else the one named like
    an image (IMAGE_LAYER_NAMES); None when none or several are."""
    layers = _rgb_layers(names)
    if len(layers) > 1:
        layers = [layer for layer in layers if layer[:-1].rsplit(".", 1)[-1].lower() in IMAGE_LAYER_NAMES]
    return layers[0] if len(layers) == 1 else None


def _with_image_layer_as_rgb(path: Path, channels: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """``channels`` with the image's layer as R, G, B (and A): unprefixed R, G, B when there are any, else the one
    layer with R, G, B (Blender, Nuke and renderers' multi-layer files: "beauty.R", "ViewLayer.Combined.R"), or of
    several the one named like an image (IMAGE_LAYER_NAMES); InputError naming the layers when that leaves
    several, or when an unprefixed channel of the same name (a lone R) would mix into it. Channels unchanged
    when no layer holds colour."""
    layers = _rgb_layers(channels)
    if not layers or "" in layers or {"Y", "RY", "BY"} <= channels.keys() or "Y" in channels:
        return channels
    layer = _image_layer(channels)
    if layer is None:
        shown = ", ".join(layer[:-1] for layer in layers)
        raise InputError(f"{path}: colour layers {shown} and no unprefixed R, G, B: which is the image is not "
                         "known; save the image's layer as R, G, B")
    renamed = {colour: layer + colour for colour in "RGBA" if layer + colour in channels}
    clashing = sorted(renamed.keys() & channels.keys())
    if clashing:
        raise InputError(f"{path}: unprefixed channel {', '.join(clashing)} beside the colour layer {layer[:-1]}: "
                         "which is the image is not known; save the image's layer as R, G, B")
    return {**{colour: channels[name] for colour, name in renamed.items()},
            **{name: plane for name, plane in channels.items() if name not in renamed.values()}}


_quieting = threading.Lock()  # sys.stdout is the process's: one reader at a time swaps it


def is_exr_file(path: Path) -> bool:
    """True for a file that begins with OpenEXR's magic number, whatever its name."""
    return starts_with(path, EXR_MAGIC)


@contextlib.contextmanager
def _openexr_quiet():
    """OpenEXR's C library prints damaged chunks on file descriptor 2, and its Python binding a "Warning: Exception
    raised reading pixel data" on sys.stdout; read_exr reports the failure in one line of its own."""
    with _quieting, c_stderr_silenced(), contextlib.redirect_stdout(io.StringIO()):
        yield


def _check_decoded_size(path: Path, headers: list[dict]) -> None:
    """Refuse, from the headers alone, an image whose pixels would not fit in memory (every part is decoded)."""
    sizes = []
    for header in headers:
        height, width = _window_size(header["dataWindow"])
        sizes.append((height, width, max(len(header.get("channels", ())), 1)))
    image = headers[_image_index([{channel.name for channel in header.get("channels", ())} for header in headers])]
    frame_height, frame_width = _window_size(image.get("displayWindow", image["dataWindow"]))
    channel_count = max(len(image.get("channels", ())), 1)
    if frame_height * frame_width > np.prod(_window_size(image["dataWindow"])):  # returned over its display window
        check_image_size(f"{path}: {channel_count} channels over the display window", frame_height, frame_width,
                         channel_count * DECODED_BYTES_PER_SAMPLE, "use a smaller image")
    if len(sizes) == 1:
        height, width, channels = sizes[0]
        check_image_size(f"{path}: {channels} channels", height, width, channels * DECODED_BYTES_PER_SAMPLE,
                         "use a smaller image")
    else:
        check_memory(f"{path}: {len(sizes)} parts", sum(height * width * channels * DECODED_BYTES_PER_SAMPLE
                                                         for height, width, channels in sizes), "use a smaller image")


def _full_resolution(pixels: np.ndarray, x_sampling: int, y_sampling: int, height: int, width: int,
                     path: Path, name: str) -> np.ndarray:
    if pixels.dtype == object:  # OpenEXR's binding: a list of samples per pixel
        raise InputError(f"{path}: a deep image (several samples per pixel): hdrcam reads flat images")
    if pixels.dtype.kind not in "fu":
        raise InputError(f"{path}: channel {name} has unsupported pixel type {pixels.dtype}")
    pixels = pixels.astype(np.float32)
    if name in ("RY", "BY") and (x_sampling, y_sampling) == (2, 2):
        pixels = _reconstructed_chroma(pixels)[:height, :width]
    elif (x_sampling, y_sampling) != (1, 1):  # another subsampled channel: nearest-neighbour upsampling
        pixels = np.repeat(np.repeat(pixels, y_sampling, axis=0), x_sampling, axis=1)[:height, :width]
    if pixels.shape != (height, width):
        raise InputError(f"{path}: channel {name} has shape {pixels.shape}, expected {(height, width)}")
    return np.ascontiguousarray(pixels)


# OpenEXR's chroma reconstruction (ImfRgbaYca.cpp, reconstructChromaHoriz/Vert): a missing sample is this
# weighted sum of the stored ones 1, 3, ..., 13 samples away on either side (a half-band filter; weights sum to 1)
CHROMA_WEIGHTS = (0.627123, -0.186077, 0.087929, -0.043159, 0.019597, -0.007540, 0.002128)


def _reconstructed_chroma(samples: np.ndarray) -> np.ndarray:
    """A chroma channel stored at every other pixel and row (2 x 2 subsampled) at full resolution, as OpenEXR's
    RGBA interface reconstructs it: stored samples kept, the others interpolated by CHROMA_WEIGHTS along rows,
    then along columns (zeros between the samples and one separable filter), beyond the edges the first and last
    stored sample repeated, as OpenEXR's FromYca pads its rows (padTmpBuf) and clamps its rows. Repeating each
    sample instead put luminance-chroma photographs 2-5 % (median) off the RGB that OpenEXR decodes; mirroring
    the edges, up to 78 % off within 13 px of them (0.023 % of Flowers.exr's pixels)."""
    kernel = np.zeros(4 * len(CHROMA_WEIGHTS) - 1, np.float32)
    centre = len(kernel) // 2
    kernel[centre] = 1.0
    for index, weight in enumerate(CHROMA_WEIGHTS):
        kernel[centre - 2 * index - 1] = kernel[centre + 2 * index + 1] = weight
    pad = len(CHROMA_WEIGHTS)  # stored samples the kernel reaches beyond an edge
    padded = np.pad(samples, pad, mode="edge")
    spread = np.zeros((2 * padded.shape[0], 2 * padded.shape[1]), np.float32)
    spread[::2, ::2] = padded
    full = cv2.sepFilter2D(spread, cv2.CV_32F, kernel, kernel, borderType=cv2.BORDER_CONSTANT)
    return full[2 * pad:2 * (pad + samples.shape[0]), 2 * pad:2 * (pad + samples.shape[1])]


def _luminance_chroma_to_rgb(luminance: np.ndarray, red_difference: np.ndarray, blue_difference: np.ndarray,
                             chromaticities) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Invert OpenEXR's RgbaYca encoding: RY = (R - Y) / Y, BY = (B - Y) / Y, Y = w . RGB."""
    weight_red, weight_green, weight_blue = luminance_weights(chromaticities)
    red = (red_difference + 1.0) * luminance
    blue = (blue_difference + 1.0) * luminance
    green = (luminance - weight_red * red - weight_blue * blue) / weight_green
    return (red.astype(np.float32), green.astype(np.float32), blue.astype(np.float32))


def luminance_weights(chromaticities) -> np.ndarray:
    """(3,) weights of R, G, B in the luminance Y of the primaries and white point ``chromaticities`` (x, y of
    red, green, blue, white): the Y row of the normalised primary matrix, as OpenEXR's RgbaYca encoding computes
    it (Imf::RGBtoXYZ; hdrcam.colorimetry.normalised_primary_matrix, in numpy: colour-science's import takes
    about a second, and the training path runs where it is absent). ValueError for a white point with y <= 0 or
    primaries on one line."""
    return normalised_primary_matrix(chromaticities)[1]


def default_channel_names(pixels: np.ndarray) -> tuple[str, ...]:
    """RGB for 3 channels, RGBA for 4, Y for a single channel."""
    count = 1 if pixels.ndim == 2 else pixels.shape[-1]
    names = {1: ("Y",), 3: ("R", "G", "B"), 4: ("R", "G", "B", "A")}
    if count not in names:
        raise ValueError(f"give channel names for a {count}-channel image")
    return names[count]


COMPRESSIONS = {"zip": OpenEXR.ZIP_COMPRESSION, "none": OpenEXR.NO_COMPRESSION}  # both read by any OpenEXR


def write_exr(path: Path, pixels: np.ndarray, *, channel_names: tuple[str, ...] | None = None,
              attributes: dict[str, Any] | None = None, half: bool = False, overwrite: bool = False,
              compression: str = "zip") -> Path:
    """Write an H x W or H x W x C array atomically as a scanline EXR (see :func:`write_exr_channels`); R, G, B
    are written straight from the interleaved array."""
    pixels = np.asarray(pixels)
    planes = pixels[..., None] if pixels.ndim == 2 else pixels
    if planes.ndim != 3:
        raise ValueError(f"expected an H x W or H x W x C image, got shape {pixels.shape}")
    names = channel_names or default_channel_names(pixels)
    if len(names) != planes.shape[-1]:
        raise ValueError(f"{len(names)} channel names for {planes.shape[-1]} channels")
    channels = {"RGB": planes} if tuple(names) == ("R", "G", "B") else \
        {name: planes[..., index] for index, name in enumerate(names)}
    return write_exr_channels(path, channels, attributes=attributes, half=half, overwrite=overwrite,
                              compression=compression)


def write_exr_channels(path: Path, channels: dict[str, np.ndarray], *, attributes: dict[str, Any] | None = None,
                       half: bool = False, overwrite: bool = False, compression: str = "zip",
                       float32_channels: tuple[str, ...] = ()) -> Path:
    """Write channels atomically as a scanline EXR.

    Each value is an H x W plane, or an H x W x 3 colour group written without a copy (OpenEXR reads the
    interleaved array with strides): under the key "RGB" as channels R, G, B, under another key K as K.R, K.G,
    K.B. A bool plane (a mask) is stored as half floats 0 and 1. ``compression``: "zip" (lossless deflate, the
    default: smaller, and slower - 2.4 s more for 24 MP of float32 RGB and a mask on 2 cores) or "none" (18-23 %
    larger for noisy float data, written at disk speed); OpenEXR reads both in every version.
    ``attributes`` holds str, int or float values (floats are stored as 32-bit). ``half`` stores 16-bit floats
    (but the keys in ``float32_channels``) and raises InputError when a value exceeds the half range;
    non-finite values are refused.
    """
    if compression not in COMPRESSIONS:
        raise ValueError(f"unknown EXR compression {compression!r}; choose from {', '.join(COMPRESSIONS)}")
    arrays = {name: np.asarray(array) for name, array in channels.items()}
    for name, array in arrays.items():
        if not (array.ndim == 2 or (array.ndim == 3 and array.shape[-1] == 3)):
            raise ValueError(f"channel {name}: expected an H x W plane or an H x W x 3 group, got shape {array.shape}")
    values = [array for array in arrays.values() if array.size and array.dtype != bool]
    lowest = min((float(array.min()) for array in values), default=0.0)  # NaN and Inf show in the extremes,
    highest = max((float(array.max()) for array in values), default=0.0)  # without a temporary the image's size
    if not (np.isfinite(lowest) and np.isfinite(highest)):
        raise InputError(f"{path}: refusing to write NaN or Inf values")
    halved = {name for name, array in arrays.items() if half and array.dtype != bool and name not in float32_channels}
    largest = max((max(float(arrays[name].max()), -float(arrays[name].min())) for name in halved
                   if arrays[name].size), default=0.0)  # no temporary of the image's size
    if largest > HALF_MAX:
        raise InputError(f"{path}: values up to {largest:.6g} exceed the half-float range ({HALF_MAX:g}); write "
                         "float32 instead")
    pixels = {name: _half_mask(array) if array.dtype == bool
              else np.ascontiguousarray(array, np.float16 if name in halved else np.float32)
              for name, array in arrays.items()}
    header = {"compression": COMPRESSIONS[compression], "type": OpenEXR.scanlineimage}
    for key, value in (attributes or {}).items():
        value = value.item() if isinstance(value, np.generic) else value
        if isinstance(value, str):  # a file name that is not UTF-8 is stored with its odd bytes escaped
            value = escaped_name(value)
        header[key] = value
    if OpenEXR.global_thread_count() < worker_threads():
        with contextlib.suppress(RuntimeError):  # threads it cannot start (a memory limit): it writes on this one
            OpenEXR.set_global_thread_count(worker_threads())  # compression of scanline blocks on every core
    with atomic_path(Path(path), overwrite=overwrite) as temporary, open(temporary, "wb") as file:
        OpenEXR.File(header, pixels).write(file)  # through a Python file: any name works, a full disk names its cause
    return Path(path)


def _half_mask(mask: np.ndarray) -> np.ndarray:
    """A bool array as half floats 0 and 1, built from their bit patterns (numpy's float16 conversion is slow)."""
    bits = mask.astype(np.uint16)
    bits *= np.uint16(0x3C00)  # IEEE 754 half 1.0
    return bits.view(np.float16)
