"""The OpenVINO forward reconstruct_frame runs on a CPU equals the PyTorch forward, and falls back visibly."""

import math
import warnings

import numpy as np
import pytest
import torch

from hdrcam.recon import cpu_forward
from hdrcam.recon.cpu_forward import CompiledForward, hdr_forward
from hdrcam.recon.network import ReconstructionNet
from hdrcam.recon.presets import preset
from hdrcam.recon.tiling import reconstruct_frame

pytest.importorskip("openvino")
CPU = torch.device("cpu")


def _trained_like_network() -> ReconstructionNet:
    """The fast preset with seeded weights, the fusion exit non-zero (at zero init it hides the other stages)."""
    torch.manual_seed(0)
    network = ReconstructionNet(preset("fast")).eval()
    with torch.no_grad():
        network.fusion.exit.weight.normal_(0.0, 0.05)
    return network


def test_compiled_forward_equals_the_pytorch_forward():
    network = _trained_like_network()
    ldr = torch.rand(1, 3, 64, 96, generator=torch.Generator().manual_seed(1))
    ldr[:, :, 20:30, 40:50] = 1.0  # a clipped patch, so the highlight stage has work
    forward = hdr_forward(network, CPU, torch.float32)
    assert isinstance(forward, CompiledForward)
    with torch.no_grad():
        expected = network(ldr).hdr
    optimised = forward(ldr)
    error = float(torch.mean((optimised - expected) ** 2))
    assert error == 0.0 or 10 * math.log10(256.0 ** 2 / error) > 100.0  # PSNR at peak 2^8, as tools/bench.py
    # float32 sums in another order: 1.9e-4 at a value of 1.0 on one thread (PyTorch's own order changes with the
    # thread count); a wrong graph is off by far more than 1e-3
    assert torch.allclose(optimised, expected, rtol=1e-4, atol=1e-3)


def test_compiled_forward_is_reused_until_the_weights_change():
    network = _trained_like_network()
    first = hdr_forward(network, CPU, torch.float32)
    assert hdr_forward(network, CPU, torch.float32) is first
    with torch.no_grad():
        network.splitting.exit.bias.add_(0.1)
    assert hdr_forward(network, CPU, torch.float32) is not first


def test_other_precisions_run_the_pytorch_forward():
    network = _trained_like_network()
    assert not isinstance(hdr_forward(network, CPU, torch.float64), CompiledForward)


def test_failure_falls_back_to_the_pytorch_forward_with_one_warning(monkeypatch):
    frame = np.random.default_rng(2).uniform(0.0, 1.0, (48, 48, 3)).astype(np.float32)
    settings = dict(psf_radius_px=4, adaptive=False, core_px=32, halo_px=8)
    optimised, _ = reconstruct_frame(_trained_like_network(), frame, **settings)

    def broken(*_arguments):
        raise RuntimeError("no compiler here\nsecond line")

    monkeypatch.setattr(cpu_forward, "CompiledForward", broken)
    monkeypatch.setattr(cpu_forward, "_by_weights", {})  # compile anew (the same weights would be reused)
    monkeypatch.setattr(cpu_forward, "_failed", set())  # and keep this failure from the other tests
    with pytest.warns(UserWarning, match="OpenVINO forward unavailable .*no compiler here.*plain PyTorch"):
        plain, _ = reconstruct_frame(_trained_like_network(), frame, **settings)
    assert not np.array_equal(plain, frame)
    np.testing.assert_allclose(optimised, plain, rtol=1e-4, atol=1e-4)


def test_a_network_loaded_again_reuses_its_compiled_model_and_other_weights_get_their_own():
    first, again = _trained_like_network(), _trained_like_network()
    cpu = torch.device("cpu")
    forward = cpu_forward.hdr_forward(first, cpu, torch.float32)
    assert isinstance(forward, cpu_forward.CompiledForward)
    reused = cpu_forward.hdr_forward(again, cpu, torch.float32)
    assert reused.compiled is forward.compiled and reused.request is not forward.request  # a request per network
    frame = torch.rand(1, 3, 32, 32, generator=torch.Generator().manual_seed(1))
    assert torch.equal(reused(frame), forward(frame))
    with torch.no_grad():
        next(again.parameters()).add_(0.01)
    assert cpu_forward.hdr_forward(again, cpu, torch.float32).compiled is not forward.compiled


def test_the_compiled_forward_keeps_the_trainable_weights_and_only_the_identity_of_the_frozen_vgg():
    """The paper preset's VGG-19 (~80 MB, frozen) is not copied; an in-place change to it still counts as a change."""
    from hdrcam.recon.vgg import load_vgg19

    network = ReconstructionNet(preset("paper"), vgg=load_vgg19(random_features=True)).eval()
    weights = cpu_forward._weights(network)
    vgg_keys = [key for key in network.state_dict() if key.startswith("splitting.vgg.")]
    assert vgg_keys and all(isinstance(weights[key], tuple) for key in vgg_keys)
    assert all(isinstance(weights[key], torch.Tensor) for key in network.trainable_state())

    def unchanged() -> bool:
        return all(cpu_forward._same(value, weights[key])
                   for key, value in cpu_forward._weights(network, copy=False).items())

    assert unchanged()
    with torch.no_grad():
        next(network.splitting.vgg.parameters()).mul_(1.5)
    assert not unchanged()


def test_weights_that_failed_to_compile_are_not_tried_again(monkeypatch):
    attempts = []

    def broken(*_arguments):
        attempts.append(1)
        raise RuntimeError("no compiler here")

    monkeypatch.setattr(cpu_forward, "CompiledForward", broken)
    monkeypatch.setattr(cpu_forward, "_by_weights", {})
    monkeypatch.setattr(cpu_forward, "_failed", set())
    with pytest.warns(UserWarning, match="OpenVINO forward unavailable"):
        hdr_forward(_trained_like_network(), CPU, torch.float32)
    loaded_again = _trained_like_network()
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no second warning
        forward = hdr_forward(loaded_again, CPU, torch.float32)
    assert len(attempts) == 1
    ldr = torch.rand(1, 3, 32, 32, generator=torch.Generator().manual_seed(3))
    with torch.no_grad():
        assert torch.equal(forward(ldr), loaded_again(ldr).hdr)
    other = _trained_like_network()
    with torch.no_grad():
        other.splitting.exit.bias.add_(0.1)
    with pytest.warns(UserWarning, match="OpenVINO forward unavailable"):  # other weights get their own try
        hdr_forward(other, CPU, torch.float32)
    assert len(attempts) == 2


def test_the_paper_network_loaded_again_has_the_digest_of_its_values_not_of_its_vgg_storage():
    from hdrcam.recon.vgg import load_vgg19

    network = ReconstructionNet(preset("paper"), vgg=load_vgg19(random_features=True)).eval()
    again = ReconstructionNet(preset("paper"), vgg=load_vgg19(random_features=True)).eval()
    assert cpu_forward._digest(again) != cpu_forward._digest(network)
    again.load_state_dict(network.state_dict())
    assert next(again.splitting.vgg.parameters()).data_ptr() != next(network.splitting.vgg.parameters()).data_ptr()
    assert cpu_forward._digest(again) == cpu_forward._digest(network)  # its compiled model is reused
    with torch.no_grad():
        next(again.splitting.vgg.parameters()).mul_(1.5)
    assert cpu_forward._digest(again) != cpu_forward._digest(network)


def test_weights_compiled_once_keep_their_model_though_a_later_try_failed(monkeypatch):
    """A passing failure (memory, a second thread compiling the same weights) must not hide a model that works."""
    network = _trained_like_network()
    assert isinstance(hdr_forward(network, CPU, torch.float32), CompiledForward)
    key = (cpu_forward._digest(network), torch.get_num_threads())
    monkeypatch.setattr(cpu_forward, "_failed", {key})
    assert isinstance(hdr_forward(_trained_like_network(), CPU, torch.float32), CompiledForward)
