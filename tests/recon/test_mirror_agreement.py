"""The mirror-image second opinion: used only for PSFs equal to their mirror image, it keeps what both passes
paint and drops what only one does."""

from __future__ import annotations

import numpy as np
import pytest

from hdrcam.api import network_windows, reconstruct
from hdrcam.recon.mirror_agreement import MIRROR_TOLERANCE, mirror_agreed, mirrored, mirrored_region, psf_mirror
from hdrcam.recon.tiling import clipped_mask, plan_regions, reconstruct_frame
from hdrcam.train.checkpoint import load_model


def spike_psf(*offsets: tuple[int, int], size: int = 9) -> np.ndarray:
    """(3, size, size) unit-sum PSF: the centre plus equal spikes at (row, column) offsets from it."""
    psf = np.zeros((3, size, size), np.float32)
    centre = size // 2
    for row, column in [(0, 0), *offsets]:
        psf[:, centre + row, centre + column] += 1.0
    return psf / psf.sum(axis=(1, 2), keepdims=True)


def test_the_mirror_used_is_one_the_psf_respects():
    assert psf_mirror(spike_psf()) == "left-right"  # a Dirac respects both; left-right comes first
    assert psf_mirror(spike_psf((0, 3), (0, -3))) == "left-right"
    assert psf_mirror(spike_psf((3, 0), (-3, 0), (0, 2))) == "up-down"
    assert psf_mirror(spike_psf((2, 3))) is None
    assert psf_mirror(load_model().psf) == "left-right"  # the shipped rank-1 DOE


def test_the_tolerance_is_relative_l1():
    """Light s added right of the centre of a unit PSF: L1 distance to its mirror image 2 s, total 1 + s."""
    for ratio, symmetric in ((0.9 * MIRROR_TOLERANCE, True), (1.1 * MIRROR_TOLERANCE, False)):
        psf = spike_psf()
        centre = psf.shape[-1] // 2
        psf[:, centre, centre + 2] += ratio / (2.0 - ratio)
        assert (psf_mirror(psf) == "left-right") is symmetric
        assert psf_mirror(psf) in ("left-right", "up-down")  # a spike on the row of the centre is up-down symmetric


@pytest.mark.parametrize("mirror", ["left-right", "up-down"])
def test_a_blotch_only_one_pass_paints_is_dropped_and_light_both_paint_is_kept(mirror):
    frame = np.full((24, 32, 3), 0.2, np.float32)
    frame[10:13, 20:23] = 1.0  # a clipped lamp, off-centre

    def estimate(image: np.ndarray, seen_mirror: str | None) -> np.ndarray:
        assert seen_mirror in (None, mirror)
        hdr = np.where(image >= 1.0, 5.0, image).astype(np.float32)  # follows the frame: equal in both passes
        hdr[2:4, 2:4] = 40.0  # fixed in image coordinates: lands elsewhere once mirrored back
        return hdr

    agreed = mirror_agreed(estimate, frame, mirror)
    assert np.all(agreed[10:13, 20:23] == 5.0)
    assert np.all(agreed[2:4, 2:4] == 0.2) and agreed.max() == 5.0
    assert np.array_equal(mirror_agreed(estimate, frame, None), estimate(frame, None))


def test_mirrored_regions_cover_the_mirrored_frames_clipped_pixels():
    frame = np.full((80, 112, 3), 0.1, np.float32)
    frame[5:9, 90:96] = 1.0
    frame[60:70, 3:7] = 1.0
    regions = plan_regions(frame, psf_radius_px=4, adaptive=True, core_px=32, halo_px=8)
    for mirror in ("left-right", "up-down"):
        covered = np.zeros(frame.shape[:2], bool)
        for region in (mirrored_region(region, mirror, frame.shape[:2]) for region in regions):
            covered[region.top:region.top + region.height, region.left:region.left + region.width] = True
        assert np.all(covered[clipped_mask(mirrored(frame, mirror))])


def test_reconstruct_keeps_the_minimum_of_the_frame_and_its_mirror_image():
    model = load_model()
    rng = np.random.default_rng(3)
    frame = np.clip(rng.uniform(0.0, 0.6, (64, 96, 3)), 0, 1).astype(np.float32)
    frame[20:26, 60:70] = 1.0
    radius = model.psf.shape[-1] // 2
    direct, _ = reconstruct_frame(model.network, frame, psf_radius_px=radius)
    mirror_pass, _ = reconstruct_frame(model.network, mirrored(frame, "left-right"), psf_radius_px=radius)
    result = reconstruct(frame, model, partner=None)  # the shipped network alone (its partner: another test)
    assert result.tiles.passes == 2 and "2 passes" in result.tiles.summary()
    assert np.allclose(result.network_hdr, np.minimum(direct, mirrored(mirror_pass, "left-right")), atol=1e-6)
    single = reconstruct(frame, model, mirror_check=False, partner=None)
    assert single.tiles.passes == 1 and np.allclose(single.network_hdr, direct, atol=1e-6)
    one_sided = reconstruct(frame, model, psf=spike_psf((2, 3), size=model.psf.shape[-1]), partner=None)
    assert one_sided.tiles.passes == 1


class _CountingProgress:
    def __init__(self):
        self.windows = 0

    def update(self, windows: int = 1) -> None:
        self.windows += windows


def test_network_windows_counts_the_windows_reconstruct_runs():
    """The progress bar's total (hdrcam.api.network_windows) is what reconstruct reports to it, with and without
    the mirror pass and for a PSF that respects no mirror."""
    model = load_model()
    frame = np.full((64, 160, 3), 0.3, np.float32)
    frame[20:26, 20:30] = 1.0
    frame[40:44, 130:140] = 1.0
    radius = model.psf.shape[-1] // 2
    regions = plan_regions(frame, psf_radius_px=radius)
    lopsided = spike_psf((2, 3), size=model.psf.shape[-1])
    for psf, mirror_check, passes in ((model.psf, True, 2), (model.psf, False, 1), (lopsided, True, 1)):
        progress = _CountingProgress()
        reconstruct(frame, model, psf=psf, mirror_check=mirror_check, progress=progress, regions=regions,
                    partner=None)
        expected = network_windows(regions, psf, mirror_check=mirror_check)
        assert progress.windows == expected == passes * sum(region.windows for region in regions) > 0
