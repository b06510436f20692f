"""Fixtures shared by the judge's tests (hdrcam.recon.consistency, hdrcam.recon.network_agreement)."""

from __future__ import annotations

import numpy as np
import pytest


@pytest.fixture
def cut_red_evidence_share():
    """A function that patches the judge's evidence fit, through the monkeypatch (or monkeypatch context) it is
    given, so that the red share is halved below STRONG_EVIDENCE_SHARE: z unchanged, so the evidence stays strong
    but no longer passes the shape-cap exemption's share test."""
    from hdrcam.recon import consistency

    fitted = consistency._evidence_shares

    def cut_in_one_channel(*arguments):
        shares, significance = fitted(*arguments)
        return np.array([consistency.STRONG_EVIDENCE_SHARE / 2, 1.0, 1.0], np.float32) * shares, significance

    def apply(patcher) -> None:
        patcher.setattr(consistency, "_evidence_shares", cut_in_one_channel)

    return apply
