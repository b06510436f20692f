"""Fixtures shared by the judge's tests (hdrcam.recon.consistency, hdrcam.recon.network_agreement)."""

from __future__ import annotations

import pytest


@pytest.fixture
def cut_evidence_share():
    """A function that patches the judge's evidence fit, through the monkeypatch (or monkeypatch context) it is
    given, so that its shares fall below STRONG_EVIDENCE_SHARE (to half of it): z unchanged, so the evidence stays
    strong but no longer passes the shape-cap exemption's share test."""
    from hdrcam.recon import consistency

    fitted = consistency._evidence_shares

    def cut(*arguments):
        shares, significance = fitted(*arguments)
        return consistency.STRONG_EVIDENCE_SHARE / 2 * shares, significance

    def apply(patcher) -> None:
        patcher.setattr(consistency, "_evidence_shares", cut)

    return apply
