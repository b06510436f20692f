"""Deployment exports of a trained network: TorchScript and ONNX, and an onnxruntime stand-in for the network.

Both take an LDR frame (1, 3, H, W) in [0, 1] and return the HDR estimate (1, 3, H, W); H and W are free
(multiples of 16, as for the network). The ONNX file carries the checkpoint's PSF, profile and preset in
its metadata so ``hdrcam reconstruct --checkpoint model.onnx`` can run the streak check and pick tiles
without the torch checkpoint.
"""

from __future__ import annotations

import io
import json
import warnings
from pathlib import Path

import numpy as np
import torch
from torch import nn

from hdrcam.errors import InputError
from hdrcam.io.atomic import write_bytes_atomic
from hdrcam.recon.network import Reconstruction, ReconstructionNet

EXPORT_SIZE_PX = 256  # the example frame traced for the TorchScript export
ONNX_EXAMPLE_PX = 64  # the example frame traced for ONNX (small: tracing is a forward; H and W stay free)


class HdrOnly(nn.Module):
    """The network with one output, the HDR estimate (what deployment needs)."""

    def __init__(self, network: ReconstructionNet):
        super().__init__()
        self.network = network

    def forward(self, ldr: torch.Tensor) -> torch.Tensor:
        return self.network(ldr).hdr


def export_torchscript(network: ReconstructionNet, path: Path, *, overwrite: bool = False) -> Path:
    example = torch.rand(1, 3, EXPORT_SIZE_PX, EXPORT_SIZE_PX)
    with torch.no_grad(), warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the tracer's notes on the U-Net's size check, fixed at export
        traced = torch.jit.trace(HdrOnly(network.eval()), example, check_trace=False)
    serialised = io.BytesIO()  # saved to a path, a full disk is a RuntimeError without the cause
    torch.jit.save(traced, serialised)
    return write_bytes_atomic(Path(path), serialised.getvalue(), overwrite=overwrite)


def onnx_bytes(network: ReconstructionNet) -> bytes:
    """The network's HDR output as a serialised ONNX model (input "ldr", output "hdr", H and W free)."""
    example = torch.rand(1, 3, ONNX_EXAMPLE_PX, ONNX_EXAMPLE_PX)
    serialised = io.BytesIO()  # in memory: a full disk then fails in write_bytes_atomic, with its cause
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the exporter's notes on the size check and InstanceNorm's mode
        torch.onnx.export(HdrOnly(network.eval()), (example,), serialised, input_names=["ldr"],
                          output_names=["hdr"], dynamo=False, opset_version=17,
                          dynamic_axes={"ldr": {2: "height", 3: "width"}, "hdr": {2: "height", 3: "width"}})
    return serialised.getvalue()


def export_onnx(network: ReconstructionNet, path: Path, metadata: dict[str, str], *,
                overwrite: bool = False) -> Path:
    try:
        import onnx
    except ImportError as error:
        raise InputError("ONNX export needs the onnx package: pip install 'hdrcam[export]'") from error
    model = onnx.load_from_string(onnx_bytes(network))
    for key, value in metadata.items():
        model.metadata_props.add(key=key, value=value)
    return write_bytes_atomic(Path(path), model.SerializeToString(), overwrite=overwrite)


class OnnxNetwork:
    """Runs an exported ONNX model with onnxruntime behind the interface reconstruct_frame uses."""

    def __init__(self, path: Path):
        try:
            import onnxruntime
        except ImportError as error:
            raise InputError("running an .onnx model needs onnxruntime: pip install 'hdrcam[export]'") from error
        try:
            self.session = onnxruntime.InferenceSession(str(path), providers=["CPUExecutionProvider"])
        except Exception as error:  # onnxruntime raises its own exception types for bad files
            raise InputError(f"{path}: not a readable ONNX model ({type(error).__name__})") from error
        self.metadata = self.session.get_modelmeta().custom_metadata_map
        if "hdrcam_psf" not in self.metadata:
            raise InputError(f"{path}: not an ONNX model exported by hdrcam (no PSF in its metadata)")

    @property
    def psf(self) -> np.ndarray:
        return np.asarray(json.loads(self.metadata["hdrcam_psf"]), np.float32)

    def to(self, device=None, dtype=None) -> "OnnxNetwork":
        if dtype not in (None, torch.float32) or (device is not None and torch.device(device).type != "cpu"):
            raise InputError("ONNX models run here in float32 on the CPU (onnxruntime's CPU provider)")
        return self

    def eval(self) -> "OnnxNetwork":
        return self

    def __call__(self, ldr: torch.Tensor) -> Reconstruction:
        hdr = torch.from_numpy(self.session.run(["hdr"], {"ldr": ldr.numpy().astype(np.float32)})[0])
        return Reconstruction(ldr, torch.zeros_like(ldr), torch.ones_like(ldr), hdr)
