"""Reconstruct a whole frame in overlapping tiles, running the network only where the frame needs it.

Tiles: a region of the frame is cut into windows of ``core + 2 halo`` pixels at a stride of ``core``
(cores of at most ``core_px``, sized so they split the region evenly); pixels a window needs from
outside the frame are reflected. Each window's output is weighted by a separable trapezoid that is 1
over its core and ramps linearly to 0 across ``2 blend`` pixels centred on the core's edges;
neighbouring ramps sum to one, so tiles join without seams, and memory is bounded by one window plus the
region's accumulators whatever the frame size. ``halo`` gives each core context from outside it.

Scene-adaptive compute ("model only what a scene requires"): streaks and highlights exist only within the
PSF's reach of a clipped pixel. With ``adaptive`` on, only those pixels are reconstructed: each
connected patch of them becomes a region of its own (patches whose windows' halos would overlap share
one region), the network runs on the windows of the regions alone, and
everything else is passed through unchanged (I_hat = the frame: nothing is clipped, nothing is spread
into it that matters). A region's output is cross-faded into the frame over ``blend`` pixels at its
inner edges. A frame with no clipped pixel skips the network entirely. With ``adaptive`` off the whole
frame is one region.
"""

from __future__ import annotations

import copy
import dataclasses
import time

import cv2
import numpy as np
import scipy.ndimage
import torch

from hdrcam.errors import InputError
from hdrcam.limits import check_memory
from hdrcam.recon.cpu_forward import hdr_forward
from hdrcam.recon.network import ReconstructionNet
from hdrcam.recon.window_sizes import DEFAULT_CORE_PX, DEFAULT_HALO_PX

CLIP_LEVEL = 0.99  # a pixel whose brightest channel reaches this (relative to white) is clipped
# memory per pixel, fast preset: a window through the network (measured: 118 bytes at 1088^2, x 4), and the
# frame-wide arrays of the whole reconstruction (README: 24 MP in 3.1 GB, ~130 bytes, x 2)
WINDOW_BYTES_PER_PIXEL = 512
FRAME_BYTES_PER_PIXEL = 256
MULTIPLE_PX = 16  # the U-Net pools four times: a window's sides are multiples of this


@dataclasses.dataclass(frozen=True)
class Region:
    """A rectangle of the frame (pixels) and the grid of windows that covers it."""

    top: int
    left: int
    height: int
    width: int
    rows: int
    columns: int
    core_height: int
    core_width: int

    @property
    def windows(self) -> int:
        return self.rows * self.columns


@dataclasses.dataclass
class TileReport:
    """What a reconstruction did: windows run, what full-frame processing would have run, pixels, seconds."""

    windows: int  # of full-frame processing at the same tile size
    windows_run: int
    network_pixels: int  # pixels the network processed, halos included
    full_frame_network_pixels: int  # the same for full-frame processing
    clipped_pixels: int
    seconds: float
    passes: int = 1  # the frame, its mirror image (hdrcam.recon.mirror_agreement), each per network; counts are totals
    networks: int = 1  # 2: a partner network ran as well (hdrcam.api.reconstruct), on every pass's windows

    def summary(self) -> str:
        if self.windows_run == 0:
            return f"no clipped pixels: highlight recovery skipped ({self.windows} windows passed through)"
        share = 100.0 * self.network_pixels / (self.full_frame_network_pixels * self.passes)
        mirror = self.passes > self.networks
        parts = (["the frame and its mirror image"] if mirror else []) + \
            ([f"{'each ' if mirror else ''}through {self.networks} networks"] if self.networks > 1 else [])
        passes = f" in {self.passes} passes ({', '.join(parts)})" if parts else ""
        return (f"{self.clipped_pixels} clipped pixels; network ran on {self.windows_run} windows{passes}, "
                f"{share:.0f} % of the pixels full-frame processing ({self.windows} windows) would run")

    def with_pass(self, other: TileReport) -> TileReport:
        """This pass's report with another pass's windows, pixels and seconds added (the mirror image's, a partner
        network's)."""
        return dataclasses.replace(self, windows_run=self.windows_run + other.windows_run,
                                   network_pixels=self.network_pixels + other.network_pixels,
                                   seconds=self.seconds + other.seconds, passes=self.passes + 1)


def clipped_mask(ldr: np.ndarray, level: float = CLIP_LEVEL) -> np.ndarray:
    """H x W bool: the brightest channel reaches ``level``."""
    return np.maximum.reduce([ldr[..., channel] for channel in range(ldr.shape[-1])]) >= level


def within_px(mask: np.ndarray, reach_px: int) -> np.ndarray:
    """H x W bool: the pixels within ``reach_px`` of a True pixel of ``mask`` in x and y (a square's reach)."""
    square = cv2.getStructuringElement(cv2.MORPH_RECT, (2 * reach_px + 1,) * 2)
    return cv2.dilate(mask.astype(np.uint8), square) > 0


def refuse_all_clipped(frame: np.ndarray, name: str = "the frame") -> None:
    """InputError when every sample of an H x W x 3 ``frame`` reached CLIP_LEVEL: an all-white frame records
    neither the scene nor a streak of its highlights, so nothing can be recovered from it (the sensor was
    flooded: a shorter exposure, a smaller aperture or less gain). A frame with some channel below white keeps
    what that channel recorded and is not refused."""
    if frame.size and np.min(frame) >= CLIP_LEVEL:
        raise InputError(f"{name}: every pixel is clipped in every channel (all white): it records no scene and no "
                         "streak to work from; take a shorter exposure")


def clipped_clusters(clipped: np.ndarray, reach_px: int) -> list[tuple[tuple[slice, slice], np.ndarray]]:
    """The clusters of clipped pixels whose reach_px squares overlap, each as (crop, own): the crop (rows,
    columns) is the cluster grown by reach_px (within the frame), where its highlights' light can land through a
    PSF of that radius; ``own`` (the crop's shape, bool) marks the cluster's own clipped pixels. Crops of two
    clusters can overlap, their reaches cannot: a crop may hold another cluster's clipped pixels, never its light."""
    square = cv2.getStructuringElement(cv2.MORPH_RECT, (2 * reach_px + 1,) * 2)
    _, labels, boxes, _ = cv2.connectedComponentsWithStats(cv2.dilate(clipped.astype(np.uint8), square),
                                                           connectivity=8)
    clusters = []
    for label, (left, top, width, height, _) in enumerate(boxes[1:], start=1):
        crop = (slice(top, top + height), slice(left, left + width))
        clusters.append((crop, clipped[crop] & (labels[crop] == label)))
    return clusters


def _ramp(length: int, halo: int, blend: int) -> np.ndarray:
    position = np.arange(length, dtype=np.float32) + 0.5
    rise = np.clip((position - (halo - blend)) / (2 * blend), 0.0, 1.0)
    return np.minimum(rise, rise[::-1])


def _grid(length: int, core_px: int, halo_px: int) -> tuple[int, int]:
    """Cores of at most ``core_px`` splitting ``length`` evenly, with core + 2 halo a multiple of 16."""
    count = -(-length // core_px)
    core = -(-(-(-length // count) + 2 * halo_px) // MULTIPLE_PX) * MULTIPLE_PX - 2 * halo_px
    return count, core


def _region(top: int, left: int, height: int, width: int, core_px: int, halo_px: int) -> Region:
    rows, core_height = _grid(height, core_px, halo_px)
    columns, core_width = _grid(width, core_px, halo_px)
    return Region(top, left, height, width, rows, columns, core_height, core_width)


def plan_regions(ldr: np.ndarray, *, psf_radius_px: int, adaptive: bool = True, core_px: int = DEFAULT_CORE_PX,
                 halo_px: int = DEFAULT_HALO_PX) -> list[Region]:
    """The regions the network must run on: all of the frame, or (adaptive) the PSF's reach of its clipped
    pixels, grown by the cross-fade width; [] when adaptive and nothing clipped."""
    height, width = ldr.shape[:2]
    check_memory(f"a {width} x {height} px frame", height * width * FRAME_BYTES_PER_PIXEL,
                 "reconstruct a crop of the frame, or use a machine with more memory")
    window_height, window_width = min(core_px, height) + 2 * halo_px, min(core_px, width) + 2 * halo_px
    check_memory(f"--tile {core_px} with --halo {halo_px} ({window_width} x {window_height} px windows)",
                 window_height * window_width * WINDOW_BYTES_PER_PIXEL, "use a smaller --tile or --halo")
    if not adaptive:
        return [_region(0, 0, height, width, core_px, halo_px)]
    clipped = clipped_mask(ldr)
    if not clipped.any():
        return []
    reach = psf_radius_px + _blend(core_px, halo_px)
    distance_px = cv2.distanceTransform((~clipped).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    near = (distance_px <= reach).astype(np.uint8)
    context = within_px(near, halo_px).astype(np.uint8)
    _, groups = cv2.connectedComponents(context, connectivity=8)
    return [_region(rows.start, columns.start, rows.stop - rows.start, columns.stop - columns.start, core_px, halo_px)
            for rows, columns in scipy.ndimage.find_objects(groups * near)]


def _blend(core_px: int, halo_px: int) -> int:
    return max(1, min(halo_px, core_px // 2) // 2)


def _reflected(indices: np.ndarray, length: int) -> np.ndarray:
    """Indices outside [0, length) mirrored about the edge pixels (OpenCV's BORDER_REFLECT_101)."""
    if length == 1:
        return np.zeros_like(indices)
    period = 2 * (length - 1)
    folded = np.abs(indices) % period
    return np.where(folded >= length, period - folded, folded)


def _run_region(forward, ldr: np.ndarray, region: Region, halo_px: int, blend: int, device, dtype,
                progress) -> np.ndarray:
    """``forward``'s HDR output over the region (region height x width x 3), windows blended."""
    window_height, window_width = region.core_height + 2 * halo_px, region.core_width + 2 * halo_px
    weight = np.outer(_ramp(window_height, halo_px, blend), _ramp(window_width, halo_px, blend))[..., None]
    span_height = region.rows * region.core_height + 2 * halo_px
    span_width = region.columns * region.core_width + 2 * halo_px
    total = np.zeros((span_height, span_width, 3), np.float32)
    weights = np.zeros((span_height, span_width, 1), np.float32)
    for row in range(region.rows):
        for column in range(region.columns):
            top, left = row * region.core_height, column * region.core_width
            rows = _reflected(np.arange(region.top + top - halo_px, region.top + top - halo_px + window_height),
                              ldr.shape[0])
            columns = _reflected(np.arange(region.left + left - halo_px,
                                           region.left + left - halo_px + window_width), ldr.shape[1])
            patch = np.ascontiguousarray(ldr[rows[:, None], columns[None, :]], np.float32)
            with torch.no_grad():
                tensor = torch.from_numpy(patch).permute(2, 0, 1)[None].to(device=device, dtype=dtype)
                output = forward(tensor)[0].permute(1, 2, 0).float().cpu().numpy()
            total[top:top + window_height, left:left + window_width] += output * weight
            weights[top:top + window_height, left:left + window_width] += weight
            if progress:
                progress.update()
    core = (slice(halo_px, halo_px + region.height), slice(halo_px, halo_px + region.width))
    return total[core] / weights[core]


def _fade(length: int, start: int, frame_length: int, blend: int) -> np.ndarray:
    """1 inside, ramping to 0 over ``blend`` px at each end that is not the frame's edge."""
    position = np.arange(length, dtype=np.float32) + 0.5
    fade = np.ones(length, np.float32)
    if start > 0:
        fade = np.minimum(fade, position / blend)
    if start + length < frame_length:
        fade = np.minimum(fade, (length - position) / blend)
    return np.clip(fade, 0.0, 1.0)


def reconstruct_frame(network: ReconstructionNet, ldr: np.ndarray, *, psf_radius_px: int, adaptive: bool = True,
                      core_px: int = DEFAULT_CORE_PX, halo_px: int = DEFAULT_HALO_PX,
                      device: torch.device = torch.device("cpu"), dtype: torch.dtype = torch.float32,
                      progress=None, regions: list[Region] | None = None) -> tuple[np.ndarray, TileReport]:
    """H x W x 3 LDR frame in [0, 1] -> H x W x 3 float32 HDR estimate and what was run.

    The windows run through :func:`hdrcam.recon.cpu_forward.hdr_forward`: OpenVINO for a ReconstructionNet
    in float32 on the CPU, the PyTorch forward otherwise.

    ``regions``: the frame's :func:`plan_regions` with the same settings, when the caller has them already."""
    started = time.perf_counter()
    height, width = ldr.shape[:2]
    frame = np.ascontiguousarray(ldr, np.float32)
    full_frame = _region(0, 0, height, width, core_px, halo_px)
    if regions is None:
        regions = plan_regions(frame, psf_radius_px=psf_radius_px, adaptive=adaptive, core_px=core_px,
                               halo_px=halo_px)
    blend = _blend(core_px, halo_px)
    hdr = frame.copy()
    if regions:
        forward = hdr_forward(_on(network, device, dtype).eval(), device, dtype)
    for region in regions:
        output = _run_region(forward, frame, region, halo_px, blend, device, dtype, progress)
        fade = np.outer(_fade(region.height, region.top, height, blend),
                        _fade(region.width, region.left, width, blend))[..., None]
        inside = (slice(region.top, region.top + region.height), slice(region.left, region.left + region.width))
        hdr[inside] += fade * (output - hdr[inside])
    return hdr, TileReport(full_frame.windows, sum(region.windows for region in regions),
                           sum(_window_pixels(region, halo_px) for region in regions),
                           _window_pixels(full_frame, halo_px), int(clipped_mask(frame).sum()),
                           time.perf_counter() - started)


def _on(network, device: torch.device, dtype: torch.dtype):
    """``network`` on ``device`` in ``dtype``: itself when it is there already, else a copy - ``Module.to``
    converts in place, so a bfloat16 run rounded the caller's float32 weights for good (the same frame's next
    float32 reconstruction then differed by up to 2.1) and a CUDA run left the model on the GPU."""
    parameter = next(network.parameters(), None) if isinstance(network, torch.nn.Module) else None
    if parameter is None or (parameter.device == torch.empty(0, device=device).device and parameter.dtype == dtype):
        return network.to(device=device, dtype=dtype)  # "cuda" is the current device's index: compared as such
    return copy.deepcopy(network).to(device=device, dtype=dtype)


def _window_pixels(region: Region, halo_px: int) -> int:
    return region.windows * (region.core_height + 2 * halo_px) * (region.core_width + 2 * halo_px)
