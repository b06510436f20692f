"""Losses: targets, exclusion loss, Eq. 15 Huber, and finite values/gradients at the extremes."""

import math

import pytest
import torch

from hdrcam.recon.losses import (GAIN_CEILING_DB, LossWeights, exclusion_loss, highlight_encoding,
                                 linear_gain_loss, reconstruction_loss, sqrt_huber_loss, stage_targets)
from hdrcam.recon.network import Reconstruction


def test_targets_split_the_radiance_exactly():
    radiance = torch.tensor([0.0, 0.3, 1.0, 7.5, 256.0])
    unsaturated, highlight = stage_targets(radiance)
    assert torch.allclose(unsaturated + highlight - 1.0, radiance, rtol=0, atol=1e-7)
    assert unsaturated.max() <= 1.0 and highlight.min() >= 1.0
    assert highlight_encoding(torch.tensor([1.0, 16.0, 256.0])).tolist() == pytest.approx([0.0, 0.5, 1.0])


def test_exclusion_loss_is_small_for_separate_edges_and_large_for_shared_ones():
    first = torch.zeros(1, 3, 32, 32)
    first[..., :, 16:] = 1.0  # a vertical edge
    apart = torch.zeros(1, 3, 32, 32)
    apart[..., 8:9, :] = 1.0  # a horizontal line: gradients on the other axis
    assert exclusion_loss(first, first) > 10 * exclusion_loss(first, apart)
    assert exclusion_loss(first, torch.zeros_like(first)) < 0.05


def test_sqrt_huber_is_zero_on_the_truth_with_a_finite_gradient_at_zero():
    truth = torch.zeros(1, 3, 4, 4)
    estimate = torch.zeros(1, 3, 4, 4, requires_grad=True)
    loss = sqrt_huber_loss(estimate, truth)
    loss.backward()
    assert float(loss.detach()) == 0.0 and torch.isfinite(estimate.grad).all()
    assert float(sqrt_huber_loss(torch.full((4,), 256.0), torch.full((4,), 1.0))) == pytest.approx(
        0.1 * (math.sqrt(256.0001) - math.sqrt(1.0001) - 0.05), rel=1e-4)


def _output(shape, value_unsaturated, value_highlight, requires_grad=True):
    tensors = [torch.full(shape, v, requires_grad=requires_grad) for v in
               (value_unsaturated, 0.0, value_highlight, value_unsaturated + value_highlight - 1.0)]
    return tensors, Reconstruction(*tensors)


@pytest.mark.parametrize("radiance_value, unsaturated, highlight", [
    (0.0, 0.0, 1.0),  # an all-black scene and an all-black estimate
    (256.0, 1.0, 256.0),  # 2^8 highlights everywhere
    (0.5, 0.5, 1.0),  # nothing saturated: an empty saturation mask
    (300.0, 0.0, 1.0),  # beyond 2^8 in the truth, nothing estimated
])
def test_total_loss_and_gradients_are_finite_at_the_extremes(radiance_value, unsaturated, highlight):
    shape = (1, 3, 16, 16)
    tensors, output = _output(shape, unsaturated, highlight)
    terms = reconstruction_loss(output, torch.full(shape, radiance_value), LossWeights(), vgg=None)
    terms["total"].backward()
    assert all(torch.isfinite(v) for v in terms.values())
    assert all(t.grad is not None and torch.isfinite(t.grad).all() for t in tensors)


def test_perfect_estimate_has_only_the_exclusion_floor():
    radiance = torch.rand(1, 3, 16, 16) * 4.0
    unsaturated, highlight = stage_targets(radiance)
    output = Reconstruction(unsaturated, torch.zeros_like(radiance), highlight, radiance)
    terms = reconstruction_loss(output, radiance, LossWeights(), vgg=None)
    assert float(terms["unsaturated"]) == 0.0 and float(terms["highlight"]) == 0.0
    assert float(terms["fusion"]) == 0.0 and float(terms["exclusion"]) < 0.01


def test_linear_gain_is_minus_the_psnr_gain_over_the_frame_per_scene():
    """Scene 0: a sun of 4 pixels at 2^8 on a grey sky, the frame clipped at 1; scene 1: nothing above white."""
    truth = torch.full((2, 3, 16, 16), 0.5)
    truth[0, :, 7:9, 7:9] = 256.0
    frame = truth.clamp(max=1.0)
    halfway = frame.clone()
    halfway[0, :, 7:9, 7:9] = 1.0 + 255.0 * (1 - 2 ** -0.5)  # sqrt(1/2) of the error left: MSE halved
    exact = linear_gain_loss(halfway, truth, frame)
    assert float(exact) == pytest.approx(0.5 * -10 * math.log10(2.0), abs=5e-3)  # scene 1 adds 0; the floor 0.004
    assert float(linear_gain_loss(frame, truth, frame)) == pytest.approx(0.0, abs=1e-6)
    # the truth itself: the gain stops at the ceiling, and its gradient stays finite
    estimate = truth.clone().requires_grad_(True)
    at_truth = linear_gain_loss(estimate, truth, frame)
    at_truth.backward()
    assert float(at_truth.detach()) == pytest.approx(0.5 * -GAIN_CEILING_DB, abs=5e-3)
    assert torch.isfinite(estimate.grad).all()
    # a scene the network makes worse than its frame costs: a lamp painted on the unclipped sky
    painted = frame.clone()
    painted[1, :, 0:2, 0:2] = 4.0
    assert float(linear_gain_loss(painted, truth, frame)) > 10.0


def test_the_linear_gain_term_joins_the_total_only_when_weighted():
    radiance = torch.rand(1, 3, 16, 16) * 4.0
    frame = radiance.clamp(max=1.0)
    _, output = _output(radiance.shape, 0.5, 1.0)
    plain = reconstruction_loss(output, radiance, LossWeights(), vgg=None, ldr=frame)
    weighted = reconstruction_loss(output, radiance, LossWeights(linear_gain=0.05), vgg=None, ldr=frame)
    assert "linear_gain" not in plain
    assert float(weighted["linear_gain"]) == pytest.approx(0.05 * float(linear_gain_loss(output.hdr, radiance, frame)))
    assert float(weighted["total"]) == pytest.approx(float(plain["total"]) + float(weighted["linear_gain"]), rel=1e-6)
    with pytest.raises(ValueError, match="captured frame"):
        reconstruction_loss(output, radiance, LossWeights(linear_gain=0.05), vgg=None)
