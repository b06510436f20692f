"""HDR metrics against analytic values, and the HDR-CNN-style blending baseline."""

import math

import numpy as np
import pytest

from hdrcam.evaluate.metrics import (PSNR_CAP_DB, PU21_PEAK, mu_law, psnr_linear, psnr_mu, pu21_encode,
                                     pu21_psnr)
from hdrcam.evaluate.scoring import hdrcnn_blend


def test_linear_psnr_of_a_unit_error_is_20_log10_256():
    truth = np.random.default_rng(0).uniform(0, 200, (16, 16, 3))
    assert psnr_linear(truth + 1.0, truth) == pytest.approx(20 * math.log10(256.0), abs=1e-9)
    assert psnr_linear(truth, truth) == PSNR_CAP_DB
    # estimates are clipped to [0, 2^8] before scoring: an overshoot past the peak costs nothing more
    assert psnr_linear(np.full((2, 2, 3), 1e6), np.full((2, 2, 3), 256.0)) == PSNR_CAP_DB
    with pytest.raises(ValueError, match="NaN"):
        psnr_linear(np.full((2, 2, 3), np.nan), truth[:2, :2])


def test_pu21_matches_the_published_anchors():
    # PU21 banding+glare maps 10,000 cd/m^2 to 595.39 and 100 cd/m^2 to about 256 (SDR-comparable scale)
    assert PU21_PEAK == pytest.approx(595.3939, abs=1e-3)
    assert float(pu21_encode(np.array(100.0))) == pytest.approx(256.4, abs=0.1)
    low = pu21_encode(np.array([0.0, 0.005, 1e-9]))
    assert np.all(np.isfinite(low)) and np.all(low >= 0.0)  # clamped at 0.005 cd/m^2: log/pow near zero
    values = pu21_encode(np.logspace(-2, 4, 50))
    assert np.all(np.diff(values) > 0)  # monotonic
    black = np.zeros((4, 4, 3))
    assert pu21_psnr(black, black) == PSNR_CAP_DB


def test_mu_law_end_points_and_psnr():
    assert mu_law(np.array([0.0, 256.0, 1e6])).tolist() == pytest.approx([0.0, 1.0, 1.0])
    assert float(mu_law(np.array(256.0 / 5000.0))) == pytest.approx(math.log(2) / math.log(5001))
    truth = np.full((4, 4, 3), 2.0)
    assert psnr_mu(truth, truth) == PSNR_CAP_DB and psnr_mu(truth * 2, truth) < 40.0


def test_hdrcnn_blend_ramps_from_095_to_1():
    reconstruction = np.full((1, 4, 3), 50.0)
    ldr = np.array([[[0.5, 0.5, 0.5], [0.95, 0.2, 0.2], [0.975, 0.3, 0.3], [1.0, 1.0, 1.0]]])
    blended = hdrcnn_blend(ldr, reconstruction)
    assert np.allclose(blended[0, 0], 0.5) and np.allclose(blended[0, 1], ldr[0, 1])
    assert np.allclose(blended[0, 2], 0.5 * ldr[0, 2] + 25.0) and np.allclose(blended[0, 3], 50.0)


def test_gains_over_the_reference_are_per_image_differences_in_scoring_order():
    from hdrcam.evaluate.report import gains_over
    from hdrcam.evaluate.scoring import ScoredImage

    def row(image, method, psnr):
        return ScoredImage(image, method, {"psnr_linear": psnr, "pu21_psnr": 0.0, "psnr_mu": 0.0}, 0.015)

    rows = [row("b", "ldr", 40.0), row("b", "hdrcam", 41.5), row("a", "ldr", 30.0), row("a", "hdrcam", 29.0)]
    np.testing.assert_allclose(gains_over(rows, "hdrcam"), [1.5, -1.0])
    np.testing.assert_allclose(gains_over(rows, "ldr"), [0.0, 0.0])


def test_the_summary_names_each_methods_worst_image_and_counts_the_harmed_ones():
    from hdrcam.evaluate.report import summary_markdown
    from hdrcam.evaluate.scoring import ScoredImage

    def row(image, method, psnr):
        return ScoredImage(image, method, {"psnr_linear": psnr, "pu21_psnr": 0.0, "psnr_mu": 0.0}, 0.015)

    gains = {"a": 1.0, "b": -0.5, "c": -0.2}  # b is harmed, c is within the 0.3 dB bar
    rows = [entry for image, gain in gains.items()
            for entry in (row(image, "ldr", 40.0), row(image, "hdrcam", 40.0 + gain))]
    summary = summary_markdown(rows, "test")
    assert "| hdrcam | 40.10 | +0.10 | -0.50 | 1 |" in summary
    assert "| ldr | 40.00 | +0.00 | +0.00 | 0 |" in summary
    assert "Worst image per method: hdrcam: b." in summary


def test_the_summary_compares_a_method_only_on_the_images_it_shares_with_the_reference():
    from hdrcam.evaluate.report import summary_markdown
    from hdrcam.evaluate.scoring import ScoredImage

    def row(image, method, psnr):
        return ScoredImage(image, method, {"psnr_linear": psnr, "pu21_psnr": 0.0, "psnr_mu": 0.0}, 0.015)

    rows = [row("a", "ldr", 40.0), row("a", "mine", 41.0), row("b", "ldr", 30.0), row("c", "mine", 60.0)]
    summary = summary_markdown(rows, "test")
    assert "| mine | 50.50 | +1.00 | +1.00 | 0 |" in summary  # c has no reference: not a gain of +25
    assert "Worst image per method: mine: a." in summary


@pytest.mark.parametrize("metric", [psnr_linear, pu21_psnr, psnr_mu])
def test_images_of_different_shapes_or_empty_ones_are_refused_not_broadcast(metric):
    """numpy broadcast a 1 x 1 truth over a 64 x 64 estimate (46.9 dB), and empty images read as NaN ones."""
    with pytest.raises(ValueError, match="shapes"):
        metric(np.ones((64, 64, 3)), np.ones((1, 1, 3)))
    with pytest.raises(ValueError, match="shapes"):
        metric(np.ones((0, 4, 3)), np.ones((0, 4, 3)))
