"""Image formation: linear FFT convolution, Poisson-Gaussian noise, clipping, ADC, mosaic, extremes."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from hdrcam.profiles import load_profile
from hdrcam.sensor import Sensor, add_noise, bayer_mosaic, fft_convolve, quantise, without_fft_round_off


def direct_convolve(image: np.ndarray, kernel: np.ndarray) -> np.ndarray:
    """out[y, x] = sum_ij image[y - i + kh // 2, x - j + kw // 2] kernel[i, j], zero outside."""
    height, width = image.shape
    kernel_height, kernel_width = kernel.shape
    out = np.zeros_like(image)
    for i in range(kernel_height):
        for j in range(kernel_width):
            dy, dx = i - kernel_height // 2, j - kernel_width // 2
            shifted = np.zeros_like(image)
            ys, xs = slice(max(dy, 0), height + min(dy, 0)), slice(max(dx, 0), width + min(dx, 0))
            ys_src, xs_src = slice(max(-dy, 0), height + min(-dy, 0)), slice(max(-dx, 0), width + min(-dx, 0))
            shifted[ys, xs] = image[ys_src, xs_src]
            out += kernel[i, j] * shifted
    return out


@pytest.mark.parametrize("kernel_shape", [(5, 5), (4, 4), (3, 6), (7, 2), (1, 1)])
def test_fft_convolution_equals_direct_convolution(kernel_shape):
    rng = np.random.default_rng(0)
    image = rng.random((3, 23, 17))
    kernel = rng.random((3, *kernel_shape))
    result = fft_convolve(torch.from_numpy(image)[None], torch.from_numpy(kernel))[0].numpy()
    for channel in range(3):
        np.testing.assert_allclose(result[channel], direct_convolve(image[channel], kernel[channel]), atol=1e-5 * image.max())


def test_convolution_is_linear_not_circular():
    image = torch.zeros(1, 1, 16, 16)
    image[..., 0, 0] = 1.0  # a point in the corner must not wrap to the opposite edges
    kernel = torch.ones(1, 5, 5) / 25
    result = fft_convolve(image, kernel)
    assert float(result[..., -3:, :].abs().max()) < 1e-7 and float(result[..., :, -3:].abs().max()) < 1e-7
    assert float(result[..., :3, :3].sum()) == pytest.approx(9 / 25, rel=1e-5)


def test_fft_round_off_is_set_to_zero_per_plane_and_a_dim_planes_light_is_kept():
    """One floor (hdrcam.sensor.without_fft_round_off) for the consistency check and the windshield fit, each plane
    against its own largest value: the fit's own floor, against the largest value of all three, set a dim
    plane's light to 0 (a red lamp's blue streak 1e-7 of its red one) with its round-off."""
    image = np.zeros((3, 40, 40), np.float32)
    image[:, 20, 20] = (1000.0, 1.0, 1e-4)
    kernel = np.zeros((3, 15, 15), np.float32)
    kernel[:, 7, 7], kernel[:, 7, 0], kernel[:, 0, 3] = 0.9, 0.07, 0.03
    raw = fft_convolve(torch.from_numpy(image), torch.from_numpy(kernel)).numpy()
    result = without_fft_round_off(torch.from_numpy(raw)).numpy()
    for plane in range(3):
        lit = direct_convolve(image[plane].astype(np.float64), kernel[plane].astype(np.float64)) > 0
        assert np.any(raw[plane][~lit] != 0.0)  # the FFT's round-off, where no light goes
        assert np.all(result[plane][~lit] == 0.0)
        np.testing.assert_allclose(result[plane][lit], raw[plane][lit])  # the light, as convolved
    assert np.all(raw[2] <= 1e-6 * raw.max())  # the global floor took the blue light for round-off


@pytest.mark.parametrize("size", [4, 5])
@pytest.mark.parametrize("radiance", [0.0, 2.0 ** 8, 2.0 ** 16])
def test_dirac_psf_at_extreme_radiance_returns_the_image(size, radiance):
    image = torch.full((1, 3, 12, 12), radiance, dtype=torch.float32)
    image[..., 3, 4] = radiance * 0.5
    psf = torch.zeros(3, size, size)
    psf[:, size // 2, size // 2] = 1.0
    result = fft_convolve(image, psf)
    assert torch.isfinite(result).all()
    torch.testing.assert_close(result, image, atol=max(radiance, 1.0) * 1e-6, rtol=1e-6)


def test_noise_statistics_match_poisson_gaussian_model():
    generator = torch.Generator().manual_seed(0)
    signal = torch.full((200_000,), 0.01, dtype=torch.float64)
    full_well, read = 20000.0, 5.0
    for differentiable in (True, False):
        noisy = add_noise(signal, full_well, read, generator, differentiable) * full_well
        assert float(noisy.mean()) == pytest.approx(200.0, rel=0.01)
        assert float(noisy.var()) == pytest.approx(200.0 + read ** 2, rel=0.03)


def test_noise_is_seeded_and_gradients_stay_finite_at_zero_signal():
    signal = torch.zeros(64, requires_grad=True)
    first = add_noise(signal, 1000.0, 0.0, torch.Generator().manual_seed(7))
    second = add_noise(signal, 1000.0, 0.0, torch.Generator().manual_seed(7))
    assert torch.equal(first, second)
    first.sum().backward()
    assert torch.isfinite(signal.grad).all()


def test_capture_clips_quantises_and_keeps_gradients():
    sensor = Sensor.from_camera(load_profile("simulated").camera)
    irradiance = torch.tensor([0.0, 0.25, 1.0, 2.0 ** 8], dtype=torch.float32).reshape(1, 1, 1, 4).repeat(1, 3, 4, 1)
    irradiance.requires_grad_(True)
    psf = torch.zeros(3, 3, 3)
    psf[:, 1, 1] = 1
    captured = sensor.capture(irradiance, psf, generator=torch.Generator().manual_seed(0))
    assert float(captured.detach().min()) >= 0.0 and float(captured.detach().max()) == 1.0
    steps = captured.detach() * sensor.adc_levels
    torch.testing.assert_close(steps, steps.round())
    captured[..., 1].sum().backward()
    assert torch.isfinite(irradiance.grad).all() and float(irradiance.grad[..., 1].abs().sum()) > 0


def test_quantise_rounds_to_adc_steps_with_straight_through_gradient():
    values = torch.tensor([0.0, 0.3, 0.49, 1.0], requires_grad=True)
    out = quantise(values, 4)
    torch.testing.assert_close(out.detach(), torch.tensor([0.0, 0.25, 0.5, 1.0]))
    out.sum().backward()
    torch.testing.assert_close(values.grad, torch.ones(4))


@pytest.mark.parametrize("pattern", ["RGGB", "BGGR", "GRBG", "GBRG"])
def test_bayer_mosaic_samples_the_named_channel_at_each_site(pattern):
    image = torch.stack([torch.full((4, 6), value) for value in (1.0, 2.0, 3.0)])
    mosaic = bayer_mosaic(image, pattern)
    lookup = {"R": 1.0, "G": 2.0, "B": 3.0}
    for position, colour in enumerate(pattern):
        row, column = divmod(position, 2)
        assert torch.all(mosaic[row::2, column::2] == lookup[colour])
