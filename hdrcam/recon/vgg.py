"""VGG-19 features (torchvision layout) for the splitting net's hypercolumn and the perceptual loss.

Nothing is downloaded. Weights come from a local torchvision-format state dict (the file torchvision
saves as ``vgg19-dcbb9e9d.pth``; keys ``features.N.weight`` / ``features.N.bias``), given by
``--vgg-weights FILE`` or the environment variable ``HDRCAM_VGG19_WEIGHTS``. Random features are used
only when a caller asks for them explicitly (tests). The network is frozen either way.

Inputs are linear RGB in [0, 1] (an LDR frame or a tone-mapped HDR image), normalised with the ImageNet
mean and deviation as torchvision's weights expect.
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import torch
from torch import nn

from hdrcam.errors import InputError

WEIGHTS_ENVIRONMENT = "HDRCAM_VGG19_WEIGHTS"
_LAYOUT = (64, 64, "M", 128, 128, "M", 256, 256, 256, 256, "M", 512, 512, 512, 512, "M", 512, 512)
# index in torchvision's vgg19().features of the ReLU after each named conv
LAYER_INDEX = {"conv1_2": 3, "conv2_2": 8, "conv3_2": 13, "conv4_2": 22, "conv5_2": 31}
HYPERCOLUMN_LAYERS = ("conv1_2", "conv2_2", "conv3_2", "conv4_2", "conv5_2")  # paper Sec. 4.1
PERCEPTUAL_LAYERS = ("conv2_2", "conv3_2", "conv4_2")  # paper Sec. 4
HYPERCOLUMN_CHANNELS = 64 + 128 + 256 + 512 + 512
_MEAN = (0.485, 0.456, 0.406)
_STD = (0.229, 0.224, 0.225)


class Vgg19Features(nn.Module):
    """torchvision's ``vgg19().features`` up to the ReLU of conv5_2; returns the named activations."""

    def __init__(self):
        super().__init__()
        layers: list[nn.Module] = []
        channels = 3
        for item in _LAYOUT:
            if item == "M":
                layers.append(nn.MaxPool2d(2, 2))
            else:
                layers += [nn.Conv2d(channels, item, 3, padding=1), nn.ReLU(inplace=False)]
                channels = item
        self.features = nn.Sequential(*layers)
        self.register_buffer("mean", torch.tensor(_MEAN).view(1, 3, 1, 1))
        self.register_buffer("std", torch.tensor(_STD).view(1, 3, 1, 1))
        self.requires_grad_(False)
        self.eval()

    def forward(self, rgb: torch.Tensor, layers: tuple[str, ...]) -> dict[str, torch.Tensor]:
        wanted = {LAYER_INDEX[name]: name for name in layers}
        last = max(wanted)
        activations = {}
        value = (rgb - self.mean) / self.std
        for index, layer in enumerate(self.features):
            value = layer(value)
            if index in wanted:
                activations[wanted[index]] = value
            if index == last:
                break
        return activations

    def train(self, mode: bool = True) -> "Vgg19Features":
        return super().train(False)  # frozen: never in training mode


def vgg_for_preset(preset, weights: Path | None, *, random_features: bool = False) -> Vgg19Features | None:
    """The VGG-19 features a network preset needs (:func:`load_vgg19`), None for a preset without them; weights
    given for such a preset are named as unused (a warning), not silently ignored."""
    if preset.vgg_features:
        return load_vgg19(weights, random_features=random_features)
    if weights is not None:
        warnings.warn(f"--vgg-weights {weights}: the {preset.name!r} preset has no VGG features; the weights are "
                      "not used")
    return None


def load_vgg19(weights: Path | None = None, *, random_features: bool = False) -> Vgg19Features:
    """VGG-19 features from ``weights`` (or $HDRCAM_VGG19_WEIGHTS); random only if ``random_features``."""
    network = Vgg19Features()
    path = weights or (Path(os.environ[WEIGHTS_ENVIRONMENT]) if os.environ.get(WEIGHTS_ENVIRONMENT) else None)
    if path is None:
        if random_features:
            return network
        raise InputError("the 'paper' preset needs VGG-19 weights: pass --vgg-weights FILE (a torchvision "
                         f"vgg19 state dict) or set {WEIGHTS_ENVIRONMENT}; they cannot be downloaded here. "
                         "Use --preset lite or fast to work without them")
    try:
        state = torch.load(Path(path), map_location="cpu", weights_only=True)
    except Exception as error:  # torch.load raises many types (pickle, zip, OS) for damaged files
        raise InputError(f"cannot read VGG-19 weights {path} ({type(error).__name__})") from error
    features = {key[len("features."):]: value for key, value in state.items() if key.startswith("features.")}
    mine = network.features.state_dict()
    missing = [key for key in mine if key not in features]
    if missing:
        raise InputError(f"{path} is not a torchvision vgg19 state dict (missing features.{missing[0]})")
    try:
        network.features.load_state_dict({key: features[key] for key in mine})
    except RuntimeError as error:
        raise InputError(f"{path}: weights do not fit VGG-19 ({str(error).splitlines()[-1].strip()})") from error
    return network
