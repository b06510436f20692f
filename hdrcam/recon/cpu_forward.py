"""The network's float32 forward on a CPU through OpenVINO: what :func:`hdrcam.recon.tiling.reconstruct_frame` runs.

PyTorch's eager forward calls oneDNN once per layer, converts between NCHW and oneDNN's blocked layout around
every convolution, and runs InstanceNorm and LeakyReLU as separate passes over memory. OpenVINO's CPU plugin
compiles the whole graph: each convolution with its bias (and activation, where no norm follows), each
InstanceNorm (as MVN) with its affine and LeakyReLU, all in one channels-last layout (two reorders in the
whole graph: in and out). On a 2-core AVX2 CPU the ``fast``
network's forward at 512^2 runs about 4x faster than PyTorch's and 1.5x faster than onnxruntime's
(tools/bench.py). The network is exported to ONNX in memory (the checkpoint is untouched) and compiled once
per set of weights and thread count, in about 0.5 s; the HDR estimate equals the PyTorch forward to
rounding (PSNR about 127 dB at peak 2^8 on the shipped network, largest difference 1e-4 relative).

If OpenVINO or onnx is missing, or the export, the compilation or its check against the PyTorch forward on
a small probe frame fails, :func:`hdr_forward` warns once (one line) and returns the plain PyTorch forward.
"""

from __future__ import annotations

import hashlib
import warnings
import weakref
from typing import Callable

import numpy as np
import torch

from hdrcam.recon.network import ReconstructionNet

PROBE_PX = 32  # side of the random frame each compiled model is checked on against the PyTorch forward
PROBE_TOLERANCE = 1e-3  # relative and absolute tolerance of that check (radiance, 1 = white)

_compiled: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()  # network -> its CompiledForward
# The OpenVINO model compiled for each (weights digest, threads), never released, so a network loaded
# again (a checkpoint's partner for each library call) reuses its compiled model. With compiled models
# released, the test suite's process died of SIGSEGV (si_code SI_KERNEL, raised on signal delivery rather than
# by a bad access) when tests/faults/test_signals_and_concurrency.py sent itself SIGTERM after
# tests/cli/test_recon_cli.py had run the two default networks; OpenVINO's CPU plugin calls sigaltstack on the
# compiling thread (gdb), so a released model apparently leaves that thread's alternate signal stack dangling.
# Not reproduced outside pytest. A compiled `fast` network holds a few MB: one per distinct set of weights.
_by_weights: dict[tuple[str, int], object] = {}
_compiled_models: list = []  # every OpenVINO model compiled here, also those that failed the probe check
# (weights digest, threads) that could not be compiled or failed the probe check: they run the PyTorch forward
# without another try for the life of the process (an export and a compilation cost seconds, and the warning was
# given once); another thread count tries, and warns, again
_failed: set[tuple[str, int]] = set()


class CompiledForward:
    """One network's HDR output compiled by OpenVINO for the CPU, with the weights and thread count it was
    compiled for.

    Calling it maps an LDR frame (N, 3, H, W) float32 in [0, 1] to the HDR estimate (N, 3, H, W), relative
    radiance (1.0 = sensor white); H and W are free (multiples of 16, as for the network)."""

    def __init__(self, network: ReconstructionNet, threads: int, compiled=None):
        """``compiled``: an OpenVINO model already compiled from these weights on ``threads`` threads (it gets
        a request of its own: one request must not run on two threads at once), else it is compiled here."""
        self.threads = threads
        self.weights = _weights(network)
        if compiled is None:
            import openvino

            from hdrcam.recon.export import onnx_bytes

            core = openvino.Core()
            # threads not pinned to cores: as fast on an idle CPU, less slowed when other processes share the cores
            compiled = core.compile_model(core.read_model(onnx_bytes(network)), "CPU", {
                "INFERENCE_NUM_THREADS": threads, "INFERENCE_PRECISION_HINT": "f32", "PERFORMANCE_HINT": "LATENCY",
                "ENABLE_CPU_PINNING": False})
            _compiled_models.append(compiled)  # never released (see _by_weights)
        self.compiled = compiled
        self.request = self.compiled.create_infer_request()

    def built_for(self, network: ReconstructionNet, threads: int) -> bool:
        """Whether the compiled model still runs ``network``'s current weights on ``threads`` threads."""
        current = _weights(network, copy=False)
        return threads == self.threads and current.keys() == self.weights.keys() and all(
            _same(current[key], self.weights[key]) for key in current)

    def __call__(self, ldr: torch.Tensor) -> torch.Tensor:
        array = np.ascontiguousarray(ldr.detach().numpy(), np.float32)
        return torch.from_numpy(np.array(self.request.infer({0: array})[self.compiled.output(0)]))


def _weights(network: ReconstructionNet, copy: bool = True) -> dict[str, torch.Tensor | tuple[int, int]]:
    """What the compiled model depends on: the trainable weights by value (copied unless ``copy`` is False), the
    frozen VGG-19's (paper preset; ~80 MB, never trained) by identity - storage address and version counter."""
    trainable = network.trainable_state()
    weights: dict[str, torch.Tensor | tuple[int, int]] = {
        key: value.detach().clone() if copy else value for key, value in trainable.items()}
    weights.update({key: (value.data_ptr(), value._version) for key, value in network.state_dict().items()
                    if key not in trainable})
    return weights


def _same(current: torch.Tensor | tuple[int, int], compiled: torch.Tensor | tuple[int, int]) -> bool:
    if isinstance(current, tuple) or isinstance(compiled, tuple):
        return current == compiled
    return current.shape == compiled.shape and torch.equal(current, compiled)


def _plain(network) -> Callable[[torch.Tensor], torch.Tensor]:
    return lambda ldr: network(ldr).hdr


def _checked(network: ReconstructionNet, threads: int) -> CompiledForward:
    """A newly compiled forward, verified against the PyTorch forward on a seeded PROBE_PX^2 frame."""
    forward = CompiledForward(network, threads)
    probe = torch.rand(1, 3, PROBE_PX, PROBE_PX, generator=torch.Generator().manual_seed(0))
    with torch.no_grad():
        expected = network(probe).hdr
    if not torch.allclose(forward(probe), expected, rtol=PROBE_TOLERANCE, atol=PROBE_TOLERANCE):
        raise ValueError("its output differs from the PyTorch forward")
    return forward


def hdr_forward(network, device: torch.device, dtype: torch.dtype) -> Callable[[torch.Tensor], torch.Tensor]:
    """The function reconstruct_frame runs on each window: LDR (N, 3, H, W) -> HDR estimate (N, 3, H, W).

    OpenVINO's compiled model (once per set of weights and torch thread count; later calls reuse it, also for
    the same weights loaded again) for a :class:`ReconstructionNet` in float32 on the CPU; ``network(ldr).hdr``
    for anything else, and - after one warning, without trying again for the same weights - when it cannot be
    compiled or disagrees with the PyTorch forward."""
    if not (isinstance(network, ReconstructionNet) and device.type == "cpu" and dtype == torch.float32):
        return _plain(network)
    threads = torch.get_num_threads()
    forward = _compiled.get(network)
    if forward is not None and forward.built_for(network, threads):
        return forward
    key = (_digest(network), threads)
    if key in _by_weights:  # these weights compiled and checked before: a request of this network's own
        forward = CompiledForward(network, threads, _by_weights[key])
    elif key in _failed:
        return _plain(network)
    else:
        try:
            forward = _checked(network, threads)
        except Exception as error:  # ImportError, the exporter's and OpenVINO's own exception types
            reason = (str(error).splitlines() or [""])[0]
            warnings.warn(f"OpenVINO forward unavailable ({type(error).__name__}: {reason}); running the plain "
                          "PyTorch forward (slower)", stacklevel=2)
            _failed.add(key)
            return _plain(network)
        _by_weights[key] = forward.compiled
    _compiled[network] = forward
    return forward


def _digest(network: ReconstructionNet) -> str:
    """SHA-256 of every weight a compiled model depends on, by value: the trainable ones and the frozen VGG-19's
    (paper preset; hashing its ~80 MB takes a fraction of the compilation it spares when the network is loaded
    again)."""
    digest = hashlib.sha256()
    for key, value in sorted(network.state_dict().items()):
        tensor = value.detach().contiguous().cpu()
        digest.update(key.encode())
        digest.update(str((tuple(tensor.shape), tensor.dtype)).encode())
        digest.update(tensor.reshape(-1).view(torch.uint8).numpy().tobytes() if tensor.numel() else b"")
    return digest.hexdigest()
