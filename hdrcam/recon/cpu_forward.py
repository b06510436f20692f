"""The network's float32 forward on a CPU through onnxruntime: what :func:`hdrcam.recon.tiling.reconstruct_frame`
runs.

PyTorch's eager forward calls oneDNN once per layer and converts between NCHW and oneDNN's blocked layout
around every convolution; InstanceNorm and LeakyReLU are separate passes over memory. onnxruntime's CPU
provider fuses each convolution with its bias and activation and keeps runs of convolutions in a blocked
channel layout (NCHWc); on a 2-core AVX2 CPU the ``fast`` network's forward at 512^2 runs about twice as fast
(tools/bench.py). The network is exported to ONNX in memory (the checkpoint is untouched), once per set of
weights and thread count, in about 0.5 s; the HDR estimate equals the PyTorch forward to rounding (PSNR above
140 dB at peak 2^8 on the shipped network).

If onnxruntime is missing, or the export, the session or its check against the PyTorch forward on a small
probe frame fails, :func:`hdr_forward` warns once (one line) and returns the plain PyTorch forward.
"""

from __future__ import annotations

import warnings
import weakref
from typing import Callable

import numpy as np
import torch

from hdrcam.recon.network import ReconstructionNet

PROBE_PX = 32  # side of the random frame each session is checked on against the PyTorch forward
PROBE_TOLERANCE = 1e-3  # relative and absolute tolerance of that check (radiance, 1 = white)

_sessions: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()  # network -> its OnnxForward


class OnnxForward:
    """An onnxruntime session of one network's HDR output, with the weights and thread count it was built for.

    Calling it maps an LDR frame (N, 3, H, W) float32 in [0, 1] to the HDR estimate (N, 3, H, W), relative
    radiance (1.0 = sensor white); H and W are free (multiples of 16, as for the network)."""

    def __init__(self, network: ReconstructionNet, threads: int):
        import onnxruntime

        from hdrcam.recon.export import onnx_bytes

        self.threads = threads
        self.weights = [value.detach().clone() for value in network.state_dict().values()]
        options = onnxruntime.SessionOptions()
        options.intra_op_num_threads = threads
        options.inter_op_num_threads = 1
        # threads sleep between runs instead of spinning: the numpy work between windows keeps both cores
        options.add_session_config_entry("session.intra_op.allow_spinning", "0")
        self.session = onnxruntime.InferenceSession(onnx_bytes(network), options,
                                                    providers=["CPUExecutionProvider"])

    def built_for(self, network: ReconstructionNet, threads: int) -> bool:
        """Whether the session still runs ``network``'s current weights on ``threads`` threads."""
        current = list(network.state_dict().values())
        return threads == self.threads and len(current) == len(self.weights) and all(
            a.shape == b.shape and torch.equal(a, b) for a, b in zip(current, self.weights))

    def __call__(self, ldr: torch.Tensor) -> torch.Tensor:
        array = np.ascontiguousarray(ldr.detach().numpy(), np.float32)
        return torch.from_numpy(self.session.run(["hdr"], {"ldr": array})[0])


def _plain(network) -> Callable[[torch.Tensor], torch.Tensor]:
    return lambda ldr: network(ldr).hdr


def _checked(network: ReconstructionNet, threads: int) -> OnnxForward:
    """A new session, verified against the PyTorch forward on a seeded PROBE_PX^2 frame."""
    forward = OnnxForward(network, threads)
    probe = torch.rand(1, 3, PROBE_PX, PROBE_PX, generator=torch.Generator().manual_seed(0))
    with torch.no_grad():
        expected = network(probe).hdr
    if not torch.allclose(forward(probe), expected, rtol=PROBE_TOLERANCE, atol=PROBE_TOLERANCE):
        raise ValueError("its output differs from the PyTorch forward")
    return forward


def hdr_forward(network, device: torch.device, dtype: torch.dtype) -> Callable[[torch.Tensor], torch.Tensor]:
    """The function reconstruct_frame runs on each window: LDR (N, 3, H, W) -> HDR estimate (N, 3, H, W).

    onnxruntime's session (built once per network, weights and torch thread count; later calls reuse it) for a
    :class:`ReconstructionNet` in float32 on the CPU; ``network(ldr).hdr`` for anything else, and - after one
    warning - when the session cannot be built or disagrees with the PyTorch forward."""
    if not (isinstance(network, ReconstructionNet) and device.type == "cpu" and dtype == torch.float32):
        return _plain(network)
    threads = torch.get_num_threads()
    forward = _sessions.get(network)
    if forward is not None and forward.built_for(network, threads):
        return forward
    try:
        forward = _checked(network, threads)
    except Exception as error:  # ImportError, the exporter's and onnxruntime's own exception types
        reason = (str(error).splitlines() or [""])[0]
        warnings.warn(f"onnxruntime forward unavailable ({type(error).__name__}: {reason}); running the plain "
                      "PyTorch forward (slower)", stacklevel=2)
        return _plain(network)
    _sessions[network] = forward
    return forward
