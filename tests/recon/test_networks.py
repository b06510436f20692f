"""Shapes, ranges and gradient flow of the three stages, every preset; VGG-19 loading; FLOP counting."""

import pytest
import torch
from torch import nn

from hdrcam.errors import InputError
from hdrcam.recon.flops import forward_gflops, parameter_count
from hdrcam.recon.network import ReconstructionNet
from hdrcam.recon.presets import PRESETS, preset
from hdrcam.recon.stages import HIGHLIGHT_PEAK
from hdrcam.recon.vgg import HYPERCOLUMN_LAYERS, Vgg19Features, load_vgg19


def _network(name: str) -> ReconstructionNet:
    torch.manual_seed(0)
    chosen = preset(name)
    return ReconstructionNet(chosen, load_vgg19(random_features=True) if chosen.vgg_features else None)


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_stage_shapes_ranges_and_gradients(name):
    network = _network(name)
    ldr = torch.rand(2, 3, 32, 48)
    ldr[:, :, 10:14, 20:30] = 1.0  # a clipped patch
    output = network(ldr)
    for image in (output.unsaturated, output.residual, output.highlight, output.hdr):
        assert image.shape == ldr.shape and torch.isfinite(image).all()
    assert output.highlight.min() >= 1.0 and output.highlight.max() <= HIGHLIGHT_PEAK
    assert output.hdr.min() >= 0.0
    (output.hdr.mean() + output.unsaturated.mean() + output.residual.mean()).backward()
    trainable = [(n, p) for n, p in network.named_parameters() if p.requires_grad]
    assert trainable and all(p.grad is not None and torch.isfinite(p.grad).all() for _, p in trainable)
    # the fusion exit starts at zero, so the layers before it get gradient only after the first update
    silent = [n for n, p in trainable if p.grad.abs().sum() == 0 and not n.startswith("fusion.")]
    assert not silent, silent
    assert network.fusion.exit.weight.grad.abs().sum() > 0


def test_untrained_network_starts_near_the_identity():
    network = _network("fast").eval()
    ldr = torch.rand(1, 3, 32, 32) * 0.9
    with torch.no_grad():
        output = network(ldr)
    assert float(output.highlight.max()) < 1.5  # no highlight predicted yet
    # fusion passes the composite I_U + I_S - 1 through unchanged at initialisation
    composite = output.unsaturated.clamp(min=0) + output.highlight - 1.0
    assert torch.allclose(output.hdr, composite.clamp(min=0.0), atol=1e-6)


def test_skipping_highlights_returns_the_unsaturated_image():
    network = _network("fast").eval()
    ldr = torch.rand(1, 3, 16, 16) * 0.5
    with torch.no_grad():
        output = network(ldr, highlights=False)
    assert torch.equal(output.hdr, output.unsaturated.clamp(min=0.0))
    assert torch.equal(output.highlight, torch.ones_like(ldr))


def test_input_size_must_suit_the_unet():
    with pytest.raises(ValueError, match="multiple of 16"):
        _network("fast")(torch.rand(1, 3, 24, 32))


def test_paper_preset_is_the_papers_shape():
    paper = preset("paper")
    assert paper.splitting_channels == 64 and paper.splitting_dilations == (1, 2, 4, 8, 16, 32, 64)
    assert len(paper.unet_channels) == 5 and paper.fusion_channels == (64, 32) and paper.vgg_features
    assert not preset("lite").vgg_features and not preset("fast").vgg_features
    with pytest.raises(InputError, match="unknown network preset"):
        preset("huge")


def test_vgg_needs_weights_unless_random_is_asked_for(monkeypatch):
    monkeypatch.delenv("HDRCAM_VGG19_WEIGHTS", raising=False)
    with pytest.raises(InputError, match="VGG-19 weights"):
        load_vgg19()


def test_vgg_loads_a_torchvision_state_dict(tmp_path, monkeypatch):
    torch.manual_seed(1)
    reference = Vgg19Features()
    state = {f"features.{k}": v for k, v in reference.features.state_dict().items()}
    state["classifier.0.weight"] = torch.zeros(2, 2)  # torchvision files hold the classifier too
    path = tmp_path / "vgg19.pth"
    torch.save(state, path)
    monkeypatch.setenv("HDRCAM_VGG19_WEIGHTS", str(path))
    loaded = load_vgg19()
    image = torch.rand(1, 3, 32, 32)
    expected, got = reference(image, HYPERCOLUMN_LAYERS), loaded(image, HYPERCOLUMN_LAYERS)
    assert all(torch.equal(expected[k], got[k]) for k in HYPERCOLUMN_LAYERS)
    assert got["conv5_2"].shape == (1, 512, 2, 2)
    torch.save({"features.0.weight": torch.zeros(1)}, tmp_path / "bad.pth")
    with pytest.raises(InputError, match="not a torchvision vgg19"):
        load_vgg19(tmp_path / "bad.pth")
    (tmp_path / "junk.pth").write_bytes(b"not a torch file")
    with pytest.raises(InputError, match="cannot read VGG-19 weights"):
        load_vgg19(tmp_path / "junk.pth")


def test_flops_of_one_convolution_are_analytic():
    layer = nn.Conv2d(4, 8, 3, padding=1)
    # 2 * (3 * 3 * 4) multiply-adds per output value, 8 x 10 x 12 outputs
    assert forward_gflops(layer, torch.zeros(1, 4, 10, 12)) == pytest.approx(2 * 36 * 8 * 120 / 1e9)
    assert parameter_count(layer) == 8 * 4 * 9 + 8


def test_presets_are_ordered_by_cost():
    costs = [forward_gflops(_network(name), torch.zeros(1, 3, 64, 64)) for name in ("fast", "lite", "paper")]
    assert costs[0] < costs[1] < costs[2]
