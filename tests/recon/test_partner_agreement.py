"""A partner network's second opinion (``reconstruct(..., partner=)``, ``--partner``): only what both networks paint
is kept, with the mirror pass as before, unless the frame's streaks show one network's proposal beyond doubt
(strong evidence; hdrcam.recon.network_agreement); the partner must have been trained behind the same PSF."""

from __future__ import annotations

import json
import types

import numpy as np
import pytest
import torch

from hdrcam.api import network_windows, reconstruct
from hdrcam.cli import main
from hdrcam.errors import InputError
from hdrcam.io.exr import write_exr
from hdrcam.recon.tiling import CLIP_LEVEL, plan_regions
from hdrcam.train.checkpoint import SHIPPED_CHECKPOINT, load_model


class Painter(torch.nn.Module):
    """A stand-in network that paints every clipped channel at ``level`` x white and keeps the rest."""

    def __init__(self, level: float):
        super().__init__()
        self.level = level

    def forward(self, ldr: torch.Tensor):
        return types.SimpleNamespace(hdr=torch.where(ldr >= CLIP_LEVEL, ldr * self.level, ldr))


class _CountingProgress:
    def __init__(self):
        self.windows = 0

    def update(self, windows: int = 1) -> None:
        self.windows += windows


@pytest.fixture(scope="module")
def psf():
    return load_model().psf


def frame_with_a_window() -> np.ndarray:
    frame = np.full((64, 96, 3), 0.3, np.float32)
    frame[20:30, 40:60] = 1.0
    return frame


def test_only_what_both_networks_paint_is_kept(psf):
    frame = frame_with_a_window()
    bright, dim = (types.SimpleNamespace(network=Painter(level), psf=psf) for level in (8.0, 2.0))
    regions = plan_regions(frame, psf_radius_px=psf.shape[-1] // 2)
    progress = _CountingProgress()
    paired = reconstruct(frame, bright, partner=dim, progress=progress, regions=regions)
    alone = reconstruct(frame, dim)
    assert np.array_equal(paired.network_hdr, alone.network_hdr)  # the per-pixel minimum: the dimmer proposal
    assert float(paired.network_hdr[25, 50, 0]) == 2.0
    assert paired.tiles.passes == 4  # the frame and its mirror image, each through both networks
    assert progress.windows == network_windows(regions, psf, partner=True) == 2 * network_windows(regions, psf) > 0


def test_a_partner_trained_behind_another_psf_is_refused(psf):
    other = np.roll(psf, 1, axis=-1)
    model, partner = types.SimpleNamespace(network=Painter(2.0), psf=psf), types.SimpleNamespace(
        network=Painter(2.0), psf=other)
    with pytest.raises(InputError, match="another PSF"):
        reconstruct(frame_with_a_window(), model, partner=partner)


def test_cli_reconstruct_with_a_partner_runs_both(tmp_path, capsys):
    source = tmp_path / "frame.exr"
    write_exr(source, frame_with_a_window(), channel_names=("R", "G", "B"))
    assert main(["reconstruct", str(source), "--partner", str(SHIPPED_CHECKPOINT), "--out", str(tmp_path / "out")]) == 0
    report = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert "in 4 passes (the frame and its mirror image, each through 2 networks)" in report["work"]


def test_cli_refuses_a_partner_behind_another_psf_before_any_work(tmp_path, capsys):
    source = tmp_path / "frame.exr"
    write_exr(source, frame_with_a_window(), channel_names=("R", "G", "B"))
    other = SHIPPED_CHECKPOINT.parent / "table2" / "dirac.pt"  # behind a bare lens
    assert main(["reconstruct", str(source), "--partner", str(other), "--out", str(tmp_path / "out")]) == 1
    error = capsys.readouterr().err
    assert "dirac.pt was trained behind another PSF" in error and "internal error" not in error
    assert not (tmp_path / "out").exists()
    assert main(["evaluate", "--partner", str(other), "--count", "1", "--size", "64",
                 "--out", str(tmp_path / "ev")]) == 1
    assert "another PSF" in capsys.readouterr().err


def _captured_lamp(psf: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A 7 x 7 lamp (rim 3 x white, centre 400 x) on 0.05, captured through ``psf`` with the default camera's
    noise: its streaks confirm an exact proposal beyond doubt (tests/recon/test_do_no_harm.py)."""
    from hdrcam.recon.consistency import NoiseModel
    from hdrcam.sensor import fft_convolve

    truth = np.full((128, 128, 3), 0.05, np.float32)
    truth[61:68, 61:68] = 3.0
    truth[64, 64] = 400.0
    planes = torch.from_numpy(np.ascontiguousarray(truth.transpose(2, 0, 1)))
    clean = fft_convolve(planes, torch.from_numpy(np.ascontiguousarray(psf, np.float32))).numpy().transpose(1, 2, 0)
    noisy = clean + NoiseModel().sigma(clean) * np.random.default_rng(0).standard_normal(clean.shape)
    return truth, np.clip(noisy, 0.0, 1.0).astype(np.float32)


def test_a_cluster_the_streaks_confirm_in_one_network_keeps_that_networks_judged_result(psf):
    """One network proposes the lamp exactly, the other paints it white (no excess): the minimum would keep a
    white lamp, but the streaks confirm the exact proposal, so its judged result and confidence are kept."""
    from hdrcam.recon.consistency import NoiseModel, make_consistent
    from hdrcam.recon.network_agreement import judge_pair

    truth, frame = _captured_lamp(psf)
    clipped = frame >= CLIP_LEVEL
    exact = np.where(clipped, np.maximum(truth, 1.0), frame).astype(np.float32)
    white = np.where(clipped, 1.0, frame).astype(np.float32)
    proposal, judged, confidence, report = judge_pair(frame, white, exact, psf, noise=NoiseModel())
    judged_exact, confidence_exact, report_exact = make_consistent(frame, exact, psf, noise=NoiseModel())
    lamp = report_exact.confirmed
    assert lamp[64, 64] and clipped.any(axis=-1)[lamp].all()
    assert np.array_equal(judged[lamp], judged_exact[lamp]) and np.array_equal(proposal[lamp], exact[lamp])
    assert np.array_equal(confidence[lamp], confidence_exact[lamp]) and confidence_exact[lamp].min() < 1.0
    assert float(judged[64, 64].mean()) >= 0.8 * 400.0
    assert float(make_consistent(frame, white, psf, noise=NoiseModel())[0][64, 64].mean()) == 1.0
    assert report.confirmed[64, 64] and 0.0 <= report.fallback_fraction < 0.5


def test_strong_streaks_keep_a_networks_judged_lamp_though_one_channel_kept_a_small_share(psf, monkeypatch,
                                                                                         cut_evidence_share):
    """The streaks show the lamp beyond doubt (z >= STRONG_EVIDENCE_Z) but the evidence keeps less than
    STRONG_EVIDENCE_SHARE of one channel: the shape cap applies (not confirmed), yet the pair keeps the exact
    network's judged lamp - its light is the judgement's, already scaled by the share - not the white minimum
    (a share test here left night lamps whose blue streaks kept 0.6-0.8 to the minimum)."""
    from hdrcam.recon import consistency
    from hdrcam.recon.network_agreement import judge_pair

    truth, frame = _captured_lamp(psf)
    clipped = frame >= CLIP_LEVEL
    exact = np.where(clipped, np.maximum(truth, 1.0), frame).astype(np.float32)
    white = np.where(clipped, 1.0, frame).astype(np.float32)
    cut_evidence_share(monkeypatch)
    judged_exact, confidence_exact, report_exact = consistency.make_consistent(frame, exact, psf,
                                                                               noise=consistency.NoiseModel())
    lamp = report_exact.strong_evidence
    assert lamp[64, 64] and not report_exact.confirmed.any()
    _, judged, confidence, report = judge_pair(frame, white, exact, psf, noise=consistency.NoiseModel())
    assert np.array_equal(judged[lamp], judged_exact[lamp]) and np.array_equal(confidence[lamp], confidence_exact[lamp])
    assert float(judged[64, 64, 1]) > 1.0 and report.strong_evidence[64, 64] and not report.confirmed.any()


@pytest.mark.parametrize("share_cut", [False, True])
def test_strong_in_both_networks_the_cluster_holding_more_light_is_kept_whole(psf, monkeypatch, share_cut,
                                                                              cut_evidence_share):
    """The other network proposes a tenth of the lamp's excess, or the lamp's light moved from its rim into its
    core: the streaks are strong evidence for both proposals, and the pair keeps the whole cluster from the one
    judgement that holds more light (never a per-pixel mixture, which the frame's upper bound need not allow),
    with that judgement's masks in the report. With the red share cut below STRONG_EVIDENCE_SHARE neither is
    confirmed (the shape cap's exemption), and the rule is the same."""
    from hdrcam.recon.consistency import NoiseModel, make_consistent
    from hdrcam.recon.network_agreement import judge_pair

    if share_cut:
        cut_evidence_share(monkeypatch)
    truth, frame = _captured_lamp(psf)
    clipped = frame >= CLIP_LEVEL
    exact = np.where(clipped, np.maximum(truth, 1.0), frame).astype(np.float32)
    dim = np.where(clipped, 1.0 + 0.1 * (exact - 1.0), frame).astype(np.float32)
    peaked = exact.copy()
    peaked[61:68, 61:68] = np.where(clipped[61:68, 61:68], 1.0, peaked[61:68, 61:68])
    peaked[64, 64] += float((exact[61:68, 61:68] - peaked[61:68, 61:68]).sum(axis=(0, 1)).mean())
    for other in (dim, peaked):
        _, judged, confidence, report = judge_pair(frame, other, exact, psf, noise=NoiseModel())
        first, first_confidence, report_first = make_consistent(frame, other, psf, noise=NoiseModel())
        second, second_confidence, report_second = make_consistent(frame, exact, psf, noise=NoiseModel())
        both = report_first.strong_evidence & report_second.strong_evidence
        assert both[64, 64]
        assert share_cut == (not (report_first.confirmed | report_second.confirmed).any())
        light = [float(np.where(clipped & both[..., None], judgement - 1.0, 0.0).sum())
                 for judgement in (first, second)]
        kept, kept_confidence, kept_report = ((first, first_confidence, report_first) if light[0] >= light[1]
                                              else (second, second_confidence, report_second))
        assert np.array_equal(judged[both], kept[both]) and np.array_equal(confidence[both], kept_confidence[both])
        assert np.array_equal(report.confirmed[both], kept_report.confirmed[both])
        assert np.array_equal(report.strong_evidence[both], kept_report.strong_evidence[both])
        swapped = judge_pair(frame, exact, other, psf, noise=NoiseModel())  # the rule, not the argument order
        assert np.array_equal(swapped[1], judged) and np.array_equal(swapped[2], confidence)
    if not share_cut:  # confirmed, the kept lamp is exempt from the shape cap and keeps its core
        assert float(judge_pair(frame, dim, exact, psf, noise=NoiseModel())[1][64, 64].mean()) >= 0.8 * 400.0


def test_without_confirming_streaks_only_what_both_paint_is_judged(psf):
    """A clipped window on a flat frame carries no streaks: the pair's result is the judged minimum."""
    from hdrcam.recon.consistency import NoiseModel, make_consistent
    from hdrcam.recon.network_agreement import judge_pair

    frame = frame_with_a_window()
    clipped = frame >= CLIP_LEVEL
    bright, dim = (np.where(clipped, level, frame).astype(np.float32) for level in (8.0, 2.0))
    proposal, judged, confidence, report = judge_pair(frame, bright, dim, psf, noise=NoiseModel())
    expected, expected_confidence, expected_report = make_consistent(frame, dim, psf, noise=NoiseModel())
    assert not report.confirmed.any() and not report.strong_evidence.any()
    assert np.array_equal(proposal, dim) and np.array_equal(judged, expected)
    assert np.array_equal(confidence, expected_confidence)
    assert report.fallen_back_pixels == expected_report.fallen_back_pixels == int(clipped.any(axis=-1).sum())


def test_the_shipped_checkpoint_runs_with_its_partner_by_default(psf):
    """reconstruct's default partner is NAME-partner.pt beside the model's NAME.pt; None runs the model alone; a
    model without a checkpoint file beside it (no ``source``) runs alone."""
    from hdrcam.api import resolve_partner
    from hdrcam.train.checkpoint import partner_checkpoint

    model = load_model()
    partner = resolve_partner(model)
    assert partner.source == partner_checkpoint(SHIPPED_CHECKPOINT) and partner.source.is_file()
    assert resolve_partner(model, None) is None
    assert resolve_partner(types.SimpleNamespace(network=Painter(2.0), psf=psf)) is None
    frame = frame_with_a_window()
    regions = plan_regions(frame, psf_radius_px=psf.shape[-1] // 2)
    assert reconstruct(frame, model, regions=regions).tiles.networks == 2
    assert reconstruct(frame, model, regions=regions, partner=None).tiles.networks == 1


def test_a_partner_file_behind_another_psf_beside_a_checkpoint_is_refused(tmp_path, capsys):
    """A NAME-partner.pt trained behind another PSF than NAME.pt is an input error, before any frame is read."""
    import shutil

    checkpoint = tmp_path / "model.pt"
    shutil.copy(SHIPPED_CHECKPOINT, checkpoint)
    shutil.copy(SHIPPED_CHECKPOINT.parent / "table2" / "dirac.pt", tmp_path / "model-partner.pt")
    source = tmp_path / "frame.exr"
    write_exr(source, frame_with_a_window(), channel_names=("R", "G", "B"))
    assert main(["reconstruct", str(source), "--checkpoint", str(checkpoint), "--out", str(tmp_path / "out")]) == 1
    error = capsys.readouterr().err
    assert "model-partner.pt was trained behind another PSF" in error and "--no-partner" in error
    assert len(error.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()
    assert main(["reconstruct", str(source), "--checkpoint", str(checkpoint), "--no-partner",
                 "--out", str(tmp_path / "out")]) == 0


def test_evaluate_runs_the_partner_it_is_given(psf):
    """A partner that paints nothing (every clipped channel at 1) takes the pair's proposal down to white but where
    the frame's streaks bear out the network alone (network_agreement: its judged cluster is kept whole)."""
    from hdrcam.data.scenes import SceneSource
    from hdrcam.evaluate.scoring import evaluate_models

    model = load_model()
    blank = types.SimpleNamespace(network=Painter(1.0), psf=model.psf)
    scores = {}
    for name, partner in (("alone", None), ("blank", {"hdrcam": blank})):
        rows, examples = evaluate_models({"hdrcam": model}, SceneSource("procedural"), size_px=128, count=3,
                                         partner=partner, examples=3)
        scores[name] = np.stack([example.outputs["hdrcam-network"] for example in examples])
    clipped = np.stack([example.outputs["ldr"] for example in examples]) >= CLIP_LEVEL
    assert clipped.any() and scores["alone"][clipped].max() > 1.5
    lowered = scores["blank"][clipped] < scores["alone"][clipped] - 1e-3
    assert lowered.any() and np.all(scores["blank"][clipped][lowered] <= 1.0 + 1e-6)  # the minimum with white
    assert np.all(scores["blank"][clipped] <= scores["alone"][clipped] + 1e-6)


def test_the_streak_fit_runs_one_network(tmp_path, capsys):
    source = tmp_path / "frame.exr"
    write_exr(source, frame_with_a_window(), channel_names=("R", "G", "B"))
    assert main(["reconstruct", str(source), "--streak-fit", "--out", str(tmp_path / "fit")]) == 0
    report = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert "networks" not in report["work"] and report["streak_fit"] != "off"
    assert main(["reconstruct", str(source), "--streak-fit", "--partner", str(SHIPPED_CHECKPOINT),
                 "--out", str(tmp_path / "both")]) == 1
    assert "one network" in capsys.readouterr().err and not (tmp_path / "both").exists()


def test_evaluate_scores_each_checkpoint_with_its_partner_unless_told_not_to(tmp_path, capsys):
    arguments = ["evaluate", "--count", "1", "--size", "64"]
    assert main(arguments + ["--out", str(tmp_path / "pair")]) == 0
    assert "Partner networks" in (tmp_path / "pair" / "summary.md").read_text()
    assert "simulated-rank1-fast-partner.pt" in (tmp_path / "pair" / "summary.md").read_text()
    assert main(arguments + ["--no-partner", "--out", str(tmp_path / "one")]) == 0
    assert "Partner networks" not in (tmp_path / "one" / "summary.md").read_text()
    with pytest.raises(SystemExit) as usage:
        main(arguments + ["--no-partner", "--partner", str(SHIPPED_CHECKPOINT), "--out", str(tmp_path / "x")])
    assert usage.value.code == 2 and "not allowed with" in capsys.readouterr().err


def test_the_report_masks_are_those_of_the_judgement_each_pixel_was_taken_from(psf, monkeypatch):
    """Strong evidence for both networks; the first's judgement also confirms the amount (shape cap lifted), the
    second's holds more light and does not: the pair takes the second's cluster, so its report must not mark the
    cluster confirmed (the union of the two networks' masks did)."""
    from hdrcam.recon import network_agreement
    from hdrcam.recon.consistency import ConsistencyReport, NoiseModel

    _, frame = _captured_lamp(psf)
    clipped = (frame >= CLIP_LEVEL).any(axis=-1)
    first = np.where(frame >= CLIP_LEVEL, 2.0, frame).astype(np.float32)
    second = np.where(frame >= CLIP_LEVEL, 5.0, frame).astype(np.float32)

    def judged_as_proposed(frame_, estimates, psf_, *, noise):
        judgements = []
        for estimate in estimates:
            strong = clipped if estimate is first or estimate is second else np.zeros_like(clipped)
            confirmed = clipped if estimate is first else np.zeros_like(clipped)
            confidence = np.ones(clipped.shape, np.float32)
            judgements.append((estimate, confidence,
                               ConsistencyReport(1, 0.0, 0.0, int(clipped.sum()), 0, confirmed, strong)))
        return judgements

    monkeypatch.setattr(network_agreement, "judge_estimates", judged_as_proposed)
    _, judged, _, report = network_agreement.judge_pair(frame, first, second, psf, noise=NoiseModel())
    assert np.array_equal(judged[clipped], second[clipped])
    assert report.strong_evidence[clipped].all() and not report.confirmed.any()
