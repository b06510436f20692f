"""tools/highlight_evidence.py: its oracle and its evidence measure against answers known by construction."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tools"))
from highlight_evidence import blob_mean_fill, evidence  # noqa: E402

from hdrcam.profiles import load_profile  # noqa: E402
from hdrcam.train.optical_capture import OpticalCapture  # noqa: E402


def test_blob_mean_fill_gives_each_clipped_blob_its_true_mean_and_keeps_the_rest():
    frame = np.full((20, 20, 3), 0.3, np.float32)
    truth = frame.copy()
    frame[2:4, 2:4] = 1.0
    truth[2:4, 2:4] = [[[2, 4, 6]], [[4, 8, 12]]]  # means 3, 6, 9
    frame[10:13, 10] = 1.0
    truth[10:13, 10] = 50.0
    filled = blob_mean_fill(frame, truth)
    np.testing.assert_allclose(filled[2:4, 2:4], np.broadcast_to([3.0, 6.0, 9.0], (2, 2, 3)))
    np.testing.assert_allclose(filled[10:13, 10], 50.0)
    untouched = np.ones((20, 20), bool)
    untouched[2:4, 2:4] = untouched[10:13, 10] = False
    np.testing.assert_array_equal(filled[untouched], frame[untouched])


def _psf(ring_share: float) -> np.ndarray:
    """(3, 15, 15): 1 - ring_share at the centre, ring_share spread evenly over the square ring 6 px out."""
    psf = np.zeros((3, 15, 15), np.float32)
    ring = np.zeros((15, 15), bool)
    ring[1, 1:14] = ring[13, 1:14] = ring[1:14, 1] = ring[1:14, 13] = True
    psf[:, ring] = ring_share / ring.sum()
    psf[:, 7, 7] = 1.0 - ring_share
    return psf


@pytest.mark.parametrize("ring_share", [0.0, 0.1])
def test_evidence_is_the_share_of_the_bright_light_the_psf_puts_on_unclipped_pixels(ring_share):
    scene = np.full((64 + 14, 64 + 14, 3), 0.2, np.float32)
    scene[38:40, 38:40] = 100.0  # a 2 x 2 lamp far above white on a dim background
    optics = OpticalCapture(load_profile("simulated"), psf=_psf(ring_share))
    share, pixels = evidence(optics, scene, seed=0)
    assert share == pytest.approx(ring_share, abs=0.01)
    assert (pixels > 20) == (ring_share > 0)
