"""Run checkpoints over a fixed test set: capture through each checkpoint's PSF and sensor, reconstruct, score.

Test scenes (hdrcam.data.scenes) are exposure-scaled so exactly 1.5 % of their pixels exceed 1 (the
paper's test protocol). Each scene is captured with the same noise seed for every method. Rows:
- ``ldr``: the captured frame itself (what a camera records), through the first checkpoint's PSF;
- ``hdrcnn-blend``: HDR-CNN-style blending (Eilertsen et al.) of the frame with that checkpoint's
  reconstruction, alpha ramping 0 -> 1 as the frame's brightest channel goes 0.95 -> 1: the network is
  trusted only where the frame clipped;
- one row per checkpoint (its label): :func:`hdrcam.api.reconstruct`, the function ``reconstruct`` and
  ``demo`` call, with its defaults: the network's highlights kept as far as the frame supports them
  (:mod:`hdrcam.recon.consistency`), the unclipped pixels the frame less the highlights' spill;
- ``LABEL-network``: the network's output alone (its two mirror passes agreed, where used), before the frame
  checked it.
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import torch

from hdrcam.api import reconstruct, resolve_partner
from hdrcam.data.saturation import clipped_fraction
from hdrcam.data.scenes import SceneSource, protocol_shortfall
from hdrcam.errors import InputError
from hdrcam.evaluate.metrics import all_metrics
from hdrcam.profiles import load_profile
from hdrcam.train.checkpoint import TrainedModel
from hdrcam.train.optical_capture import OpticalCapture

NETWORK_SUFFIX = "-network"  # LABEL-network: a checkpoint's network alone
BLEND_START = 0.95  # HDR-CNN's blending threshold on the brightest channel


@dataclasses.dataclass
class ScoredImage:
    image: str
    method: str
    metrics: dict[str, float]
    clipped_fraction: float


@dataclasses.dataclass
class Example:
    image: str
    truth: np.ndarray
    outputs: dict[str, np.ndarray]  # method -> H x W x 3


def hdrcnn_blend(ldr: np.ndarray, reconstruction: np.ndarray) -> np.ndarray:
    """(1 - alpha) LDR + alpha reconstruction, alpha = clip((max_c LDR - 0.95) / 0.05, 0, 1)."""
    alpha = np.clip((ldr.max(axis=-1, keepdims=True) - BLEND_START) / (1.0 - BLEND_START), 0.0, 1.0)
    return (1.0 - alpha) * ldr + alpha * reconstruction


def check_test_crop(size_px: int) -> None:
    """InputError unless ``size_px`` is a test crop the network takes: a multiple of 16, at least 32."""
    if isinstance(size_px, bool) or not isinstance(size_px, int) or size_px % 16 or size_px < 32:
        raise InputError(f"--size must be a multiple of 16 and at least 32, got {size_px!r}")


def evaluate_models(models: dict[str, TrainedModel], source: SceneSource, *, size_px: int, count: int,
                    psf: np.ndarray | None = None, seed: int = 0, examples: int = 3, mirror_check: bool = True,
                    place_highlights: bool = False,
                    partner="auto", progress=None, unscored: list[tuple[str, str]] | None = None
                    ) -> tuple[list[ScoredImage], list[Example]]:
    """Score every model (label -> model) on the test set; ``psf`` overrides the checkpoints' PSFs;
    ``mirror_check``, ``place_highlights``, ``partner``: :func:`hdrcam.api.reconstruct`'s options of those names
    ("auto": each model's own partner checkpoint, where it has one), or for ``partner`` a dict label -> partner (a label
    missing: none). A scene the protocol cannot scale is left out with a warning, and appended to ``unscored``
    (where given) as (name, reason)."""
    partners = {label: resolve_partner(model, partner.get(label) if isinstance(partner, dict) else partner)
                for label, model in models.items()}
    capture_psfs = {label: model.psf if psf is None else psf for label, model in models.items()}
    captures = {label: OpticalCapture(load_profile(model.profile), psf=capture_psfs[label])
                for label, model in models.items()}
    margin = max(capture.margin_px for capture in captures.values())
    first = next(iter(models))
    rows, shown = [], []
    for index, (name, scene, scene_seed) in enumerate(source.test_scenes(size_px, margin, count)):
        truth = scene[margin:margin + size_px, margin:margin + size_px]
        fraction = clipped_fraction(truth)
        shortfall = protocol_shortfall(truth)  # test_scenes' own test, so its warnings agree with this one
        if shortfall:
            warnings.warn(f"{name}: not scored - scaled as the protocol asks, {shortfall}")
            if unscored is not None:
                unscored.append((name, f"scaled as the protocol asks, {shortfall}"))
            if progress:
                progress.update()
            continue
        radiance = torch.from_numpy(scene).permute(2, 0, 1)[None]
        outputs = {}
        for label, model in models.items():
            capture = captures[label]
            crop = margin - capture.margin_px
            local = radiance[..., crop:radiance.shape[-2] - crop, crop:radiance.shape[-1] - crop]
            with torch.no_grad():
                ldr, _ = capture(local, torch.Generator().manual_seed(seed * 100_003 + scene_seed))
            frame = ldr[0].permute(1, 2, 0).numpy().astype(np.float32)
            result = reconstruct(frame, model, psf=capture_psfs[label], mirror_check=mirror_check,
                                 place_highlights=place_highlights,
                                 partner=partners[label])
            if label == first:
                outputs["ldr"] = frame
                outputs["hdrcnn-blend"] = hdrcnn_blend(frame, result.network_hdr)
            outputs[label] = result.hdr
            outputs[f"{label}{NETWORK_SUFFIX}"] = result.network_hdr
        rows += [ScoredImage(name, method, all_metrics(image, truth), fraction) for method, image in outputs.items()]
        if index < examples:
            shown.append(Example(name, truth, outputs))
        if progress:
            progress.set_postfix_str(name, refresh=False)
            progress.update()
    return rows, shown
