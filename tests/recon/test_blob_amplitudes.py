"""The shared non-negative least-squares fit of blob brightness (damped Jacobi) against known answers."""

import torch

from hdrcam.recon.blob_amplitudes import fit_blob_amplitudes


def _two_blobs(size: int = 40):
    """Label image with blob 1 (a 3 x 3 square) and blob 2 (a 2 x 4 bar) far apart; a ring-shaped kernel."""
    labels = torch.zeros(size, size, dtype=torch.int64)
    labels[8:11, 8:11] = 1
    labels[28:30, 20:24] = 2
    shapes = (labels > 0).to(torch.float32).expand(3, size, size).clone()
    kernel = torch.zeros(3, 9, 9)
    kernel[:, 4, 0] = kernel[:, 4, 8] = kernel[:, 0, 4] = kernel[:, 8, 4] = 0.01  # tails 4 px out, no centre
    return labels, shapes, kernel


def test_recovers_known_amplitudes_from_their_tails():
    from hdrcam.sensor import fft_convolve
    labels, shapes, kernel = _two_blobs()
    truth = torch.tensor([[0.0, 50.0, 3.0], [0.0, 200.0, 0.5], [0.0, 7.0, 120.0]])
    target = fft_convolve(truth[:, labels.reshape(-1)].reshape(shapes.shape) * shapes, kernel)
    weight = (labels == 0).to(torch.float32)
    fitted = fit_blob_amplitudes(target, weight, shapes, labels.reshape(-1), 3, kernel, 200)
    assert torch.allclose(fitted, truth, rtol=1e-3, atol=1e-3)


def test_amplitudes_stay_non_negative_and_the_background_stays_zero():
    labels, shapes, kernel = _two_blobs()
    target = -torch.ones(3, *labels.shape)  # nothing non-negative explains it better than 0
    fitted = fit_blob_amplitudes(target, torch.ones(1, *labels.shape), shapes, labels.reshape(-1), 3, kernel, 20,
                                 prior_mean=torch.full((3, 3), 5.0))
    assert (fitted == 0).all()


def test_without_data_the_prior_keeps_its_mean():
    """Empty weight (every pixel clipped): the data says nothing, a_k stays e_k; no division blows up."""
    labels, shapes, kernel = _two_blobs()
    prior = torch.tensor([[0.0, 4.0, 9.0]]).expand(3, 3).clone()
    fitted = fit_blob_amplitudes(torch.rand(3, *labels.shape), torch.zeros(1, *labels.shape), shapes,
                                 labels.reshape(-1), 3, kernel, 10, prior_weight=torch.ones(3, 3), prior_mean=prior)
    assert torch.isfinite(fitted).all() and torch.allclose(fitted[:, 1:], prior[:, 1:])
