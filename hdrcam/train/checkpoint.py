"""Checkpoints: one torch file holding the network, the optics it was trained through and how it was made.

Format ``hdrcam-checkpoint/1`` (a dict, loadable with ``torch.load(weights_only=True)``):
  format, preset, profile, step, config (the TrainConfig as a dict), psf (3 x S x S float32 tensor: the PSF
  the network expects, unit sum per channel), network (state dict without the frozen VGG-19),
  doe (None, or {kind, feature_pitch_m, heights_m, parameters}), and for resumable run checkpoints also
  optimizer and noise_generator (torch generator state); scenes need no saved state (hdrcam.train.batches).
Writes are atomic: a crash mid-write leaves the previous checkpoint intact.
"""

from __future__ import annotations

import dataclasses
import io
import zipfile
from pathlib import Path

import numpy as np
import torch

from hdrcam.errors import InputError, missing_input
from hdrcam.io.atomic import write_bytes_atomic
from hdrcam.recon.network import ReconstructionNet
from hdrcam.recon.presets import preset as preset_named
from hdrcam.recon.vgg import vgg_for_preset

CHECKPOINT_FORMAT = "hdrcam-checkpoint/1"
SHIPPED_CHECKPOINT = Path(__file__).resolve().parent.parent / "checkpoints" / "simulated-rank1-fast.pt"
PARTNER_SUFFIX = "-partner"  # NAME-partner.pt beside NAME.pt: a second network trained behind the same PSF


def partner_checkpoint(path: Path) -> Path:
    """Where the partner of checkpoint ``path`` lives: NAME-partner.pt beside NAME.pt (hdrcam.api.reconstruct
    takes it when the file exists; finetune writes it)."""
    path = Path(path)
    return path.with_name(path.stem + PARTNER_SUFFIX + path.suffix)


def recorded_checkpoint(recorded: str | Path) -> Path:
    """The checkpoint a run recorded as its start: the file itself, or, where a shipped checkpoint (or its
    partner) was recorded by another installation's path that is not here, this installation's copy."""
    path = Path(recorded)
    shipped = SHIPPED_CHECKPOINT.parent / path.name
    if not path.is_file() and path.parent.name == SHIPPED_CHECKPOINT.parent.name and shipped.is_file():
        return shipped
    return path


def save_checkpoint(path: Path, state: dict, *, overwrite: bool = True) -> Path:
    """Write ``state`` (see the module docstring) atomically."""
    serialised = io.BytesIO()  # torch.save to a path reports a full disk as a RuntimeError without the cause
    torch.save({"format": CHECKPOINT_FORMAT, **state}, serialised)
    return write_bytes_atomic(Path(path), serialised.getvalue(), overwrite=overwrite)


def read_checkpoint(path: Path) -> dict:
    """Load and check a checkpoint file; a one-line InputError when it is missing, damaged or foreign."""
    path = Path(path)
    if not path.is_file():
        raise missing_input(path, "a checkpoint file", missing=f"checkpoint {path} does not exist")
    if _is_torchscript(path):
        raise InputError(f"{path}: a TorchScript export (hdrcam export), not an hdrcam checkpoint; give the checkpoint "
                         "it was exported from (design or finetune's model.pt)")
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as error:  # torch raises many types for damaged files
        raise InputError(f"{path}: not a readable checkpoint ({type(error).__name__})") from error
    if not isinstance(state, dict) or state.get("format") != CHECKPOINT_FORMAT:
        raise InputError(f"{path}: not an hdrcam checkpoint (format {CHECKPOINT_FORMAT} expected)")
    return state


def _is_torchscript(path: Path) -> bool:
    """True for a TorchScript archive: a zip holding ARCHIVE/code/ (a checkpoint's zip holds only data.pkl and data)."""
    try:
        with zipfile.ZipFile(path) as archive:
            return any("/code/" in name for name in archive.namelist())
    except (zipfile.BadZipFile, OSError, ValueError):
        return False


@dataclasses.dataclass
class TrainedModel:
    """A network ready to reconstruct, with the PSF and profile it was trained for."""

    network: ReconstructionNet
    psf: np.ndarray  # (3, S, S)
    profile: str
    preset: str
    step: int
    source: Path
    fixed_psf: str | None = None  # the fixed PSF it was trained behind (dirac, windshield, a file), None for a DOE


def load_network_weights(network: ReconstructionNet, weights: dict, source: Path | str) -> None:
    """``weights`` (a checkpoint's "network" state) into ``network``; a one-line InputError naming ``source``
    when they do not match its preset (keys missing or unknown: another preset or hdrcam version). The VGG
    features, loaded from their own file and not saved, may be absent."""
    own = network.state_dict()
    resized = [key for key, value in weights.items() if key in own and getattr(value, "shape", None) != own[key].shape]
    missing = [key for key in own if key not in weights and not key.startswith("splitting.vgg.")]
    unexpected = [key for key in weights if key not in own]
    if missing or unexpected or resized:
        raise InputError(f"{source}: network weights do not match preset {network.preset.name!r} ({len(missing)} "
                         f"missing, {len(unexpected)} unknown, {len(resized)} of another size: another preset or "
                         "hdrcam version)")
    network.load_state_dict(weights, strict=False)


def load_model(path: Path | None = None, *, vgg_weights: Path | None = None,
               random_vgg: bool = False) -> TrainedModel:
    """The network of checkpoint ``path`` (default: the shipped one) in eval mode on the CPU."""
    path = Path(path) if path else SHIPPED_CHECKPOINT
    state = read_checkpoint(path)
    preset = preset_named(state["preset"])
    vgg = vgg_for_preset(preset, vgg_weights, random_features=random_vgg)
    network = ReconstructionNet(preset, vgg)
    load_network_weights(network, state["network"], path)
    tensors = [state["psf"], *(weights for weights in state["network"].values()
                               if torch.is_tensor(weights) and weights.is_floating_point())]
    if not all(bool(torch.isfinite(tensor).all()) for tensor in tensors):
        raise InputError(f"{path}: the checkpoint holds NaN or Inf weights (its training diverged); use another")
    network.eval()
    return TrainedModel(network, state["psf"].numpy(), state["profile"], preset.name, int(state["step"]), path,
                        (state.get("config") or {}).get("psf"))
