"""tools/judge_bias.py: the judge handed proposals made from the truth, on frames whose answer is known."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tools"))
from judge_bias import factors, kept_shares  # noqa: E402

from hdrcam.recon.consistency import NoiseModel  # noqa: E402
from tests.recon.test_do_no_harm import convolve  # noqa: E402
from tests.test_highlight_evidence_tool import _psf  # noqa: E402


def _far_ring_psf() -> np.ndarray:
    """(3, 25, 25): 0.9 at the centre, 0.1 spread over the square ring 12 px out - beyond the judge's local bound
    (LOCAL_BOUND_PX) from every pixel of a 4 px lamp (so only its exact, cluster-wide bound applies; a ring partly
    within reach is the known failure in tests/recon/test_do_no_harm.py)."""
    psf = np.zeros((3, 25, 25), np.float32)
    ring = np.zeros((25, 25), bool)
    ring[0, :] = ring[24, :] = ring[:, 0] = ring[:, 24] = True
    psf[:, ring] = 0.1 / ring.sum()
    psf[:, 12, 12] = 0.9
    return psf


def test_on_a_lamp_whose_streaks_are_seen_the_judge_keeps_a_dim_proposal_and_lowers_a_bright_one():
    truth = np.full((96, 96, 3), 0.2, np.float32)
    truth[46:50, 46:50] = 40.0  # a lamp far above white on a flat, dim background
    psf = _far_ring_psf()  # a tenth of the light 12 px out: unclipped ring pixels record it
    frame = np.clip(convolve(truth, psf), 0.0, 1.0)
    total, (dim, exact, bright) = kept_shares(frame, truth, psf, NoiseModel(), [0.25, 1.0, 4.0])
    assert total > 0
    assert dim == pytest.approx(0.25, abs=0.02)  # never raised above what was proposed
    assert exact == pytest.approx(1.0, abs=0.1)
    assert bright == pytest.approx(1.0, abs=0.15)  # a 4 x too bright lamp lowered to about the truth


def test_without_a_psf_that_reaches_unclipped_pixels_nothing_above_white_is_kept():
    truth = np.full((64, 64, 3), 0.2, np.float32)
    truth[30:34, 30:34] = 40.0
    dirac = _psf(0.0)
    _, shares = kept_shares(np.clip(convolve(truth, dirac), 0.0, 1.0), truth, dirac, NoiseModel(), [1.0, 4.0])
    assert shares == [0.0, 0.0]


def test_factors_are_positive_and_sorted():
    assert factors("4,0.25,1") == [0.25, 1.0, 4.0]
    for text in ("", "1,-2", "a,b", "0", "inf", "1,nan"):
        with pytest.raises(Exception, match="positive numbers"):
            factors(text)
