"""Pictures for people: log-scaled PSFs and colour-mapped height maps as 8-bit RGB arrays, tone-mapped HDR
previews turned upright."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import cv2
import numpy as np

from hdrcam.parallel import strips, worker_threads


def log_psf_rgb(psf: np.ndarray, decades: float = 5.0) -> np.ndarray:
    """(3, S, S) PSF -> S x S x 3 uint8, log10 scale over ``decades`` below the brightest value."""
    peak = float(np.max(psf))
    scaled = np.log10(np.maximum(np.asarray(psf, np.float64) / max(peak, 1e-300), 10.0 ** -decades))
    return np.round((scaled / decades + 1.0).clip(0, 1).transpose(1, 2, 0) * 255).astype(np.uint8)


def heightmap_rgb(heights_m: np.ndarray, h_max_m: float) -> np.ndarray:
    """Height map -> H x W x 3 uint8 (viridis, 0 .. h_max)."""
    grey = np.round((np.asarray(heights_m) / h_max_m).clip(0, 1) * 255).astype(np.uint8)
    return cv2.cvtColor(cv2.applyColorMap(grey, cv2.COLORMAP_VIRIDIS), cv2.COLOR_BGR2RGB)


def side_by_side(images: list[np.ndarray], height_px: int = 512, gap_px: int = 8) -> np.ndarray:
    """Scale RGB images to a common height (nearest neighbour, pixels stay visible) and join them."""
    panels = []
    for image in images:
        width = max(1, round(image.shape[1] * height_px / image.shape[0]))
        panels.append(cv2.resize(image, (width, height_px), interpolation=cv2.INTER_NEAREST))
        panels.append(np.full((height_px, gap_px, 3), 255, np.uint8))
    return np.concatenate(panels[:-1], axis=1)


SCALED_LUMINANCE_CAP = np.float32(1e30)  # shown as white (x / (1 + x) = 1 in float32); beyond float32's range
# the product overflowed to inf, inf / (1 + inf) is NaN, and a pixel of 1e38 on a dim background showed black
STRIP_ROWS = 256  # previews are computed a strip of rows at a time: memory stays small at 24 MP
REC709_LUMINANCE = np.array([0.2126, 0.7152, 0.0722], np.float32)
SRGB_TABLE_CELLS = 2 ** 16  # display values [0, 1] are sRGB-encoded by looking up which of this many equal cells
# they fall in (a power of two, so scaling by it is exact; at most 2 ** 16, so a cell index fits uint16)


def _srgb_code_table(cells: int) -> np.ndarray:
    """uint8 sRGB code of the centre of each of ``cells`` equal cells of display values [0, 1] (float64 curve)."""
    centre = (np.arange(cells) + 0.5) / cells
    encoded = np.where(centre <= 0.0031308, 12.92 * centre, 1.055 * centre ** (1 / 2.4) - 0.055)
    return np.round(encoded * 255).astype(np.uint8)


SRGB_CODES = _srgb_code_table(SRGB_TABLE_CELLS)


def _finite_rgb(strip: np.ndarray) -> np.ndarray:
    """float32 copy with NaN, +-inf and negative values set to 0."""
    rgb = np.fmax(np.asarray(strip, np.float32), 0.0)  # fmax takes 0 over NaN
    rgb[rgb == np.inf] = 0.0
    return rgb


def luminance_of(rgb: np.ndarray) -> np.ndarray:
    """Rec. 709 luminance (H x W float32) of linear H x W x 3 float32 RGB, by OpenCV's channel transform: a
    matrix-vector product by BLAS would wake its own threads, which then spin beside the strips' pool."""
    if rgb.size == 0:  # cv2.transform returns None for an empty image
        return np.zeros(rgb.shape[:-1], rgb.dtype)
    return cv2.transform(rgb, REC709_LUMINANCE[None]).reshape(rgb.shape[:-1])


def log_average_luminance(hdr_rgb: np.ndarray) -> float:
    """exp(mean(log(Y + 1e-6))) of a linear RGB image (Rec. 709 luminance)."""
    def log_sum(rows: slice) -> float:
        luminance = luminance_of(_finite_rgb(hdr_rgb[rows]))
        return float(np.log(luminance.astype(np.float64) + 1e-6).sum())

    with ThreadPoolExecutor(worker_threads()) as pool:
        total = sum(pool.map(log_sum, strips(hdr_rgb.shape[0], STRIP_ROWS)), 0.0)  # added in strip order
    return float(np.exp(total / (hdr_rgb.shape[0] * hdr_rgb.shape[1])))


def reduced_for_preview(hdr_rgb: np.ndarray, max_side_px: int) -> np.ndarray:
    """Linear H x W x 3 shrunk by the smallest whole factor that brings its longer side to ``max_side_px`` or
    less, each output pixel the mean of a factor x factor block (light averaged in linear units, as a camera
    with larger pixels would record it); unchanged when already that small."""
    factor = -(-max(hdr_rgb.shape[:2]) // max_side_px)
    if factor <= 1:
        return hdr_rgb
    height, width = hdr_rgb.shape[0] // factor, hdr_rgb.shape[1] // factor
    return cv2.resize(np.ascontiguousarray(hdr_rgb[:height * factor, :width * factor], np.float32), (width, height),
                      interpolation=cv2.INTER_AREA)


def tonemap_rgb(hdr_rgb: np.ndarray, key: float = 0.18, log_average: float | None = None) -> np.ndarray:
    """Linear H x W x 3 HDR -> uint8 sRGB preview: global Reinhard on luminance (log-average to ``key``).

    ``log_average`` fixes the exposure (e.g. that of a reference image, so several images compare fairly).
    The sRGB encoding is a look-up: each display value (linear, clipped to [0, 1]) gets the code of the centre of
    its cell among SRGB_TABLE_CELLS equal cells (SRGB_CODES), one code off the exact curve at most, and only
    within half a cell (1 / 131072) of a boundary between two codes."""
    log_average = log_average_luminance(hdr_rgb) if log_average is None else log_average
    preview = np.empty(hdr_rgb.shape[:2] + (3,), np.uint8)

    def map_strip(rows: slice) -> None:
        rgb = _finite_rgb(hdr_rgb[rows])
        luminance = luminance_of(rgb)
        factor = np.float32(key / log_average)
        with np.errstate(over="ignore"):  # the cap over a tiny factor may be inf: no luminance is capped then
            scaled = np.minimum(luminance, SCALED_LUMINANCE_CAP / factor) * factor
        display_gain = scaled / (1.0 + scaled) / np.maximum(luminance, 1e-12)  # display value per linear unit
        cell = np.minimum(rgb * (display_gain * np.float32(SRGB_TABLE_CELLS))[..., None], SRGB_TABLE_CELLS - 1)
        preview[rows] = SRGB_CODES.take(cell.astype(np.uint16))  # the cell index: display value x cells, truncated

    with ThreadPoolExecutor(worker_threads()) as pool:
        list(pool.map(map_strip, strips(hdr_rgb.shape[0], STRIP_ROWS)))
    return preview


def display_oriented(image: np.ndarray, orientation: int) -> np.ndarray:
    """``image`` (H x W or H x W x C, as the sensor recorded it) turned upright as its EXIF Orientation code asks:
    1 unchanged, 2 mirrored left to right, 3 turned 180 degrees, 4 mirrored top to bottom, 5 transposed, 6 turned
    90 degrees clockwise, 7 transposed and turned 180 degrees, 8 turned 90 degrees anticlockwise (5 to 8 swap
    width and height). A view, no copy."""
    if orientation >= 5:
        image = image.swapaxes(0, 1)
    return image[::-1 if orientation in (3, 4, 7, 8) else 1, ::-1 if orientation in (2, 3, 6, 7) else 1]


def confidence_preview(confidence: np.ndarray) -> np.ndarray:
    """H x W confidence in [0, 1] -> H x W x 3 uint8: white where the frame supports the value (or recorded
    it), through yellow to red where the reconstruction fell back to the frame."""
    level = np.clip(np.nan_to_num(np.asarray(confidence, np.float32)), 0.0, 1.0)
    rgb = np.stack([np.ones_like(level), 0.3 + 0.7 * level, level], axis=-1)
    return np.round(rgb * 255).astype(np.uint8)


def radial_profile(psf: np.ndarray) -> np.ndarray:
    """(3, S, S) -> (3, S // 2 + 1): mean over rings of whole-pixel radius about the centre pixel."""
    size = psf.shape[-1]
    y, x = np.mgrid[:size, :size] - size // 2
    ring = np.round(np.hypot(y, x)).astype(int).ravel()
    counts = np.bincount(ring)
    return np.stack([np.bincount(ring, weights=channel.ravel()) / counts for channel in psf])[:, :size // 2 + 1]


def radial_profile_plot(psf: np.ndarray, size_px: int = 512, decades: float = 7.0) -> np.ndarray:
    """A log-scale plot of each channel's radial profile (red, green, blue lines) as size x size RGB."""
    profile = radial_profile(psf)
    image = np.full((size_px, size_px, 3), 255, np.uint8)
    margin = 40
    span = size_px - 2 * margin
    top = np.log10(max(float(profile.max()), 1e-300))
    cv2.rectangle(image, (margin, margin), (margin + span, margin + span), (0, 0, 0), 1)
    for decade in range(int(decades) + 1):
        y = margin + round(span * decade / decades)
        cv2.line(image, (margin, y), (margin + span, y), (220, 220, 220), 1)
        cv2.putText(image, f"1e{int(np.ceil(top)) - decade}", (2, y + 4), cv2.FONT_HERSHEY_PLAIN, 0.8, (0, 0, 0))
    cv2.putText(image, f"radius 0 .. {profile.shape[1] - 1} px", (margin, size_px - 12), cv2.FONT_HERSHEY_PLAIN,
                1.0, (0, 0, 0))
    radius = np.arange(profile.shape[1])
    for channel, colour in enumerate(((220, 0, 0), (0, 160, 0), (0, 0, 220))):
        level = np.log10(np.maximum(profile[channel], 10.0 ** (np.ceil(top) - decades)))
        xs = margin + span * radius / max(radius[-1], 1)
        ys = margin + span * (np.ceil(top) - level) / decades
        points = np.stack([xs, ys.clip(margin, margin + span)], axis=1).round().astype(np.int32)
        cv2.polylines(image, [points], False, colour, 2)
    return image


def line_plot(series: dict[str, tuple[np.ndarray, np.ndarray]], title: str, size_px: tuple[int, int] = (640, 400),
              log_y: bool = True) -> np.ndarray:
    """Lines (name -> (x, y)) on one set of axes as an RGB image; y on a log10 scale when ``log_y``."""
    width, height = size_px
    image = np.full((height, width, 3), 255, np.uint8)
    left, top, right, bottom = 60, 30, width - 10, height - 30
    cv2.rectangle(image, (left, top), (right, bottom), (0, 0, 0), 1)
    cv2.putText(image, title, (left, 20), cv2.FONT_HERSHEY_PLAIN, 1.0, (0, 0, 0))
    transform = (lambda v: np.log10(np.maximum(v, 1e-12))) if log_y else (lambda v: v)
    xs = np.concatenate([np.asarray(x, float) for x, _ in series.values()])
    ys = np.concatenate([transform(np.asarray(y, float)) for _, y in series.values()])
    if xs.size == 0:
        return image
    x_low, x_high = float(xs.min()), float(max(xs.max(), xs.min() + 1))
    y_low, y_high = float(ys.min()), float(max(ys.max(), ys.min() + 1e-6))
    for label, value in ((y_high, top + 4), (y_low, bottom)):
        text = f"1e{label:.1f}" if log_y else f"{label:.3g}"
        cv2.putText(image, text, (2, value), cv2.FONT_HERSHEY_PLAIN, 0.8, (0, 0, 0))
    cv2.putText(image, f"{x_low:.0f}", (left, height - 10), cv2.FONT_HERSHEY_PLAIN, 0.8, (0, 0, 0))
    cv2.putText(image, f"{x_high:.0f}", (right - 40, height - 10), cv2.FONT_HERSHEY_PLAIN, 0.8, (0, 0, 0))
    colours = ((0, 0, 0), (220, 0, 0), (0, 150, 0), (0, 0, 220), (200, 120, 0), (150, 0, 150))
    for index, (name, (x, y)) in enumerate(series.items()):
        colour = colours[index % len(colours)]
        px = left + (right - left) * (np.asarray(x, float) - x_low) / (x_high - x_low)
        py = bottom - (bottom - top) * (transform(np.asarray(y, float)) - y_low) / (y_high - y_low)
        cv2.polylines(image, [np.stack([px, py], axis=1).round().astype(np.int32)], False, colour, 1)
        cv2.putText(image, name, (right - 150, top + 16 * (index + 1)), cv2.FONT_HERSHEY_PLAIN, 0.9, colour)
    return image
