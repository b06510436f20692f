"""The public pipeline: one reconstruction that ``hdrcam reconstruct``, ``hdrcam evaluate`` and ``hdrcam demo``
all call, so what is scored is exactly what users get.

    import hdrcam
    result = hdrcam.reconstruct(frame)            # frame: H x W x 3 float in [0, 1], linear, 1 = sensor white
    result.hdr, result.confidence, result.report  # H x W x 3 relative radiance, H x W in [0, 1], what happened
"""

from __future__ import annotations

import dataclasses
import functools
import numbers
from pathlib import Path

import numpy as np
import torch

from hdrcam.errors import InputError
from hdrcam.optics.psf_file import unit_sum_psf
from hdrcam.recon.colour_fill import checked_neutral, fill_from_unclipped_channels
from hdrcam.recon.consistency import ConsistencyReport, NoiseModel, make_consistent
from hdrcam.recon.highlight_placement import place_highlights as place_highlight_light
from hdrcam.recon.highlight_refinement import refine_highlight_amplitudes
from hdrcam.recon.highlight_spill import subtract_highlight_spill
from hdrcam.recon.mirror_agreement import mirror_agreed, mirrored_region, psf_mirror
from hdrcam.recon.network_agreement import judge_pair
from hdrcam.recon.tiling import TileReport, clipped_mask, reconstruct_frame, refuse_all_clipped
from hdrcam.recon.window_sizes import DEFAULT_CORE_PX, DEFAULT_HALO_PX, MIN_TILE_PX

FRAME_RANGE_SLACK = 0.01  # black-level noise and demosaicing overshoot just outside [0, 1] are clipped, not refused


class FrameError(InputError, ValueError):
    """A frame that is not a captured LDR frame (shape, NaN or Inf, values outside [0, 1])."""


@dataclasses.dataclass
class Reconstruction:
    """What :func:`reconstruct` returns. Images are float32, linear, relative radiance: 1.0 = the sensor's
    white at the frame's exposure."""

    hdr: np.ndarray  # H x W x 3: the reconstruction
    network_hdr: np.ndarray  # H x W x 3: the network's output (every pass agreed; with a partner, the proposal
    # network_agreement.judge_pair took per pixel) before the frame checked it
    confidence: np.ndarray  # H x W in [0, 1]: 1 = the frame supports the value (or recorded it); 0 = fell back
    tiles: TileReport
    consistency: ConsistencyReport
    streak_fit: str  # the optional streak fit's summary, or "off"
    placement: str = "off"  # the optional highlight placement's summary, or "off"
    colour_filled: int = 0  # clipped channel samples raised to what the pixel's unclipped channels show

    @property
    def fallback_fraction(self) -> float:
        """Share of the network's proposed highlight excess the frame did not support."""
        return self.consistency.fallback_fraction


def reconstruct(frame: np.ndarray, model=None, *, psf: np.ndarray | None = None, noise: NoiseModel | None = None,
                adaptive: bool = True, tile_px: int = DEFAULT_CORE_PX, halo_px: int = DEFAULT_HALO_PX,
                streak_fit: bool = False, place_highlights: bool = False, mirror_check: bool = True,
                device: torch.device | str = "cpu",
                dtype: torch.dtype = torch.float32, progress=None, regions=None, partner="auto",
                neutral_rgb=(1.0, 1.0, 1.0)) -> Reconstruction:
    """Reconstruct one captured LDR frame into linear HDR (paper Sec. 4, with the frame as the final judge).

    ``frame``: H x W x 3 linear camera RGB in [0, 1] (1 = white level). ``model``: a
    :class:`hdrcam.train.checkpoint.TrainedModel` (default: the shipped checkpoint) or any object with ``network``
    and ``psf``. ``psf``: the (3, k, k) PSF the frame was taken through (a calibration's measured psf.exr, read with
    hdrcam.optics.psf_file.load_psf; default: the model's), normalised here to unit sum per channel. Arrays and
    models, not files: a path is an InputError naming the reader to use. ``noise``: the camera's shot/read noise
    (default: that of the model's capture profile; :class:`NoiseModel`'s 25,000 e- full well and 4 e- read noise for
    a model without one). ``tile_px`` (at least MIN_TILE_PX) and ``halo_px``: the windows' largest core and their
    context, in pixels. ``partner``: a second model trained for the same PSF - "auto" (default): the checkpoint
    NAME-partner.pt beside the model's NAME.pt where there is one (the shipped checkpoint has one), None: the model
    alone, a checkpoint path, or a model. With a partner both networks run (twice the network time) and only what
    both paint is kept (their per-pixel minimum), except on clusters whose streaks confirm one network's own
    proposal beyond doubt (hdrcam.recon.network_agreement; the judge runs three times): independently trained
    networks seldom paint the same window the frame cannot refute.

    Steps: the network runs on the regions around clipped pixels (hdrcam.recon.tiling); with ``mirror_check``
    (default) and a PSF equal to its mirror image, also on the mirrored frame, and only what both answers paint
    is kept (their per-pixel minimum, hdrcam.recon.mirror_agreement; twice the network time); optionally the
    streak fit refits each blob's brightness (hdrcam.recon.highlight_refinement; off by default: it raised
    highlights past the truth on real photographs; one network only: with it, partner "auto" means none and
    a given partner is an InputError); the estimate is then made consistent with the frame -
    clipped channels at least 1, each highlight lowered wherever its light re-imaged through the PSF would
    exceed what the frame recorded beyond noise (hdrcam.recon.consistency); a channel that clipped where another
    did not is then raised to at least what the unclipped channels and the highlight's hue show
    (hdrcam.recon.colour_fill; ``neutral_rgb``: the RGB a grey surface records in the frame - equal channels,
    the default, for a white-balanced frame, a RAW file's as-shot neutral for its camera RGB); unclipped pixels
    are the frame less the kept highlights' spill (hdrcam.recon.highlight_spill, Eq. 6). With
    ``place_highlights`` (off by default: on the validation photographs it changed nothing yet;
    hdrcam.recon.highlight_placement), light is then added where long streaks say a blob's light sits (a sun
    inside its glow) and the judge vets the result again, so the confidence map and the report are the second
    judge's. The confidence map is the judge's (the share of the proposed excess it kept); the fill leaves it
    as it is and ``colour_filled`` counts the samples it raised. A frame clipped in every channel of every
    pixel records nothing to reconstruct from: InputError (hdrcam.recon.tiling.refuse_all_clipped).
    """
    for name, value, reader in (("frame", frame, "hdrcam.io.ldr_frame.read_ldr_frame(path)"),
                                ("model", model, "hdrcam.load_network_model(path)"),
                                ("psf", psf, "hdrcam.optics.psf_file.load_psf(path)")):
        if isinstance(value, (str, Path)):  # numpy read a path as a string to convert, or a model had no .psf
            raise InputError(f"reconstruct's {name} is an array or a model, not a file ({value}); read it with "
                             f"{reader}")
    if model is None:
        from hdrcam.train.checkpoint import load_model

        model = load_model()
    refuse_windshield_network(model)
    if noise is not None and not isinstance(noise, NoiseModel):
        raise InputError(f"noise {noise!r}: a hdrcam.recon.consistency.NoiseModel (full well and read noise, e-)")
    device = checked_device(device, dtype)
    checked_neutral(neutral_rgb)
    psf = model.psf if psf is None else unit_sum_psf(psf)
    frame = np.ascontiguousarray(frame, np.float32)
    if frame.ndim != 3 or frame.shape[-1] != 3 or 0 in frame.shape:
        raise FrameError(f"frame must be H x W x 3 with H, W >= 1, got shape {frame.shape}")
    if not np.isfinite(frame).all():
        raise FrameError("frame has NaN or Inf pixels: a captured frame holds finite values in [0, 1]")
    if frame.min() < -FRAME_RANGE_SLACK or frame.max() > 1.0 + FRAME_RANGE_SLACK:
        raise FrameError(f"frame values span [{frame.min():.3g}, {frame.max():.3g}]; a captured LDR frame lies in "
                         "[0, 1] (1 = the sensor's white level): is it an HDR image or unnormalised?")
    if isinstance(tile_px, bool) or not isinstance(tile_px, numbers.Integral) or tile_px < MIN_TILE_PX:
        raise InputError(f"tile {tile_px!r} px: a window's core is a whole number of pixels, at least {MIN_TILE_PX} "
                         "(smaller cores run the network almost only on their halo)")
    if isinstance(halo_px, bool) or not isinstance(halo_px, numbers.Integral) or halo_px < 0:
        raise InputError(f"halo {halo_px!r} px: a whole number of pixels, 0 or more")
    frame = np.clip(frame, 0.0, 1.0)
    refuse_all_clipped(frame)
    if streak_fit and isinstance(partner, str) and partner == "auto":
        partner = None  # the streak fit refits one network's proposal
    partner = resolve_partner(model, partner)
    if streak_fit and partner is not None:
        raise InputError("the streak fit refits one network's proposal: run it without a partner "
                         "(--no-partner, partner=None)")
    networks = [model.network] + ([partner.network] if partner is not None else [])
    reports = []

    def network_pass(network, image: np.ndarray, mirror: str | None) -> np.ndarray:
        planned = regions if regions is None or mirror is None else \
            [mirrored_region(region, mirror, image.shape[:2]) for region in regions]
        hdr, report = reconstruct_frame(network, image, psf_radius_px=psf.shape[-1] // 2, adaptive=adaptive,
                                        core_px=tile_px, halo_px=halo_px, device=torch.device(device),
                                        dtype=dtype, progress=progress, regions=planned)
        reports.append(report)
        return hdr

    mirror = psf_mirror(psf) if mirror_check else None
    proposals = [mirror_agreed(functools.partial(network_pass, network), frame, mirror) for network in networks]
    tiles = dataclasses.replace(reports[0], networks=len(networks))
    for report in reports[1:]:
        tiles = tiles.with_pass(report)
    noise = noise or profile_noise(model)
    fit_summary = "off"
    clipped = clipped_mask(frame)
    if partner is not None:
        network_hdr, consistent, confidence, report = judge_pair(frame, *proposals, psf, noise=noise)
    else:
        network_hdr = estimate = proposals[0]
        if streak_fit:
            estimate, fit = refine_highlight_amplitudes(frame, network_hdr, psf, clipped)
            fit_summary = fit.summary()
        consistent, confidence, report = make_consistent(frame, estimate, psf, noise=noise)
    consistent, filled = fill_from_unclipped_channels(frame, consistent, neutral_rgb)
    hdr = subtract_highlight_spill(frame, consistent, psf, clipped)
    placement_summary = "off"
    if place_highlights:
        proposal, placement = place_highlight_light(frame, hdr, psf, noise=noise)
        placement_summary = placement.summary()
        if placement.placed_px:
            consistent, confidence, report = make_consistent(frame, proposal, psf, noise=noise)  # hdr + the excess
            consistent, filled = fill_from_unclipped_channels(frame, consistent, neutral_rgb)
            hdr = subtract_highlight_spill(frame, consistent, psf, clipped)
    return Reconstruction(hdr, network_hdr, confidence, tiles, report, fit_summary, placement_summary, filled)


def checked_device(device: torch.device | str, dtype: torch.dtype) -> torch.device:
    """``device`` as a torch device; InputError for a name torch does not know, CUDA where torch sees none, and a
    half-precision ``dtype`` on a CPU (many times slower there: 5.7 s against 0.8 s for float32 on a 64 px
    frame), as the command line refuses them."""
    try:
        device = torch.device(device)
    except (RuntimeError, TypeError) as error:
        raise InputError(f"device {device!r}: {(str(error).splitlines() or [''])[0]}") from None
    if device.type == "cuda" and not torch.cuda.is_available():
        raise InputError(f"device {device}: torch sees no CUDA device")
    if device.type == "cpu" and dtype in (torch.float16, torch.bfloat16):
        raise InputError(f"{dtype} on the CPU runs many times slower than float32, with no gain in memory that "
                         "matters there: use float32, or a CUDA device")
    return device


def network_windows(regions, psf: np.ndarray, *, mirror_check: bool = True, partner: bool = False) -> int:
    """How many windows :func:`reconstruct` with ``regions`` (hdrcam.recon.tiling.plan_regions of the frame) runs
    the network on: each region's windows, twice when ``mirror_check`` and the (3, k, k) PSF equals its mirror
    image, twice again with a ``partner`` model (a progress bar's total)."""
    passes = 2 if mirror_check and psf_mirror(np.asarray(psf, np.float32)) else 1
    return passes * (2 if partner else 1) * sum(region.windows for region in regions)


def load_network_model(path, *, vgg_weights=None):
    """A :class:`hdrcam.train.checkpoint.TrainedModel` from a checkpoint, or from an .onnx file written by
    ``hdrcam export`` (run with onnxruntime)."""
    from hdrcam.train.checkpoint import TrainedModel, load_model

    if path and Path(path).suffix.lower() == ".onnx":
        from hdrcam.recon.export import OnnxNetwork

        network = OnnxNetwork(Path(path))
        model = TrainedModel(network, network.psf, network.metadata["hdrcam_profile"], "onnx", 0, Path(path),
                             network.metadata.get("hdrcam_fixed_psf"))
    else:
        model = load_model(path, vgg_weights=vgg_weights)
    refuse_windshield_network(model)
    return model


def refuse_windshield_network(model) -> None:
    """InputError for a network trained behind windshield streaks (design --psf windshield): it removes streaks
    (destreak), not clipped highlights; the message says how destreak runs it."""
    if getattr(model, "fixed_psf", None) != "windshield":
        return
    source = getattr(model, "source", "the model")
    runs_it = "destreak runs it from the checkpoint it was exported from" if getattr(model, "preset", "") == "onnx" \
        else f"hdrcam destreak --method network --checkpoint {source}"
    raise InputError(f"{source}: a windshield network (design --psf windshield): it removes windshield streaks "
                     f"({runs_it}), not clipped highlights")


def resolve_partner(model, partner="auto", *, vgg_weights=None):
    """:func:`reconstruct`'s ``partner`` -> the model to run beside ``model``, or None: "auto" = the checkpoint
    NAME-partner.pt beside the model's NAME.pt (hdrcam.train.checkpoint.partner_checkpoint) where that file
    exists, None = none, a checkpoint path = that checkpoint, a model = itself. A partner behind another PSF
    than the model's, or unreadable, is an InputError (naming --no-partner when it was found beside NAME.pt)."""
    if isinstance(partner, str) and partner == "auto":
        from hdrcam.train.checkpoint import partner_checkpoint

        source = getattr(model, "source", None)
        path = partner_checkpoint(source) if source else None
        if not (path and path.is_file()):
            return None
        hint = f" ({path.name} is taken as {Path(source).name}'s partner; --no-partner / partner=None runs it alone)"
        try:
            partner = load_network_model(path, vgg_weights=vgg_weights)
            check_partner(model, partner)
        except InputError as error:
            raise InputError(f"{error}{hint}") from error
        return partner
    if isinstance(partner, (str, Path)):
        partner = load_network_model(partner, vgg_weights=vgg_weights)
    if partner is not None:
        if not (hasattr(partner, "network") and hasattr(partner, "psf")):
            raise TypeError(f"partner must be 'auto', None, a checkpoint path or a model, got {type(partner).__name__}")
        check_partner(model, partner)
    return partner


def check_partner(model, partner) -> None:
    """InputError unless ``partner`` was trained behind ``model``'s PSF (the same (3, k, k) float32 PSF to 1e-6
    absolute): :func:`reconstruct`'s ``partner`` must be, and commands check it before any work."""
    first, second = np.asarray(model.psf, np.float32), np.asarray(partner.psf, np.float32)
    if first.shape != second.shape or not np.allclose(first, second, atol=1e-6):
        raise InputError(f"{getattr(partner, 'source', 'the partner')} was trained behind another PSF than "
                         f"{getattr(model, 'source', 'the model')}: a partner must share its model's PSF")


def profile_noise(model) -> NoiseModel:
    """The shot and read noise of the camera in the model's capture profile (NoiseModel() without one)."""
    if not getattr(model, "profile", None):
        return NoiseModel()
    from hdrcam.profiles import load_profile

    camera = load_profile(model.profile).camera
    return NoiseModel(camera.full_well_e, camera.read_noise_e)
