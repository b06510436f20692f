"""Do no harm: an HDR estimate made consistent with the frame it came from (paper Eq. 6).

The frame is y = clip(P * H + eta): on an unclipped pixel it measured the scene convolved with the PSF.
An estimate proposes, for each cluster of clipped pixels (hdrcam.recon.tiling.clipped_clusters) and each
colour channel c, an excess E >= 0 over the clip level on the pixels where channel c clipped. The frame can
only take that excess down, never up, so the result is never brighter than the proposal:

- Floor. The judged value of a clipped channel is at least the clip level, max(estimate, 1), because the
  sensor recorded white there (a network may say 0.06); channels that did not clip keep the frame. This is
  the output's convention: the bound below charges the clipped pixels the estimate's own light
  B = min(estimate, 1), so it holds for B + E, and the floored output re-imaged may exceed it by P * (1 - B).
- Upper bound, per unclipped pixel. The scene under the streaks is non-negative, so the re-imaged excess may
  add at most what the frame recorded beyond the clipped pixels' own light up to the clip level:
  (P * E)(x) <= max(y(x) - (P * B)(x), 0) + K_SIGMA sigma(y(x)) + TOLERANCE, B = min(estimate, 1) on clipped
  channels (0 elsewhere), sigma from the camera's shot and read noise (relative units, 1 = full well). Where the
  own light alone over-explains a pixel (a hot pixel charged at the clip level beside dark neighbours), no excess
  can satisfy it, and the exact scale below - a minimum over the pixels the excess reaches - made it a veto: a
  hot pixel 12-30 px from a lamp kept none of the lamp (tests/recon/test_do_no_harm.py; what remains there
  is a known limit); so the excess may still add what noise hides there (tools/results/real-data/slack-floor).
  B is the estimate's, not 1: a pixel next to a lamp clips from the lamp's spill alone while its own radiance is far
  below 1 (a 3 x 3 lamp at 200 x white clips 77 pixels, 68 of them dimmer than white), and charging those at 1
  cut an exactly proposed lamp to 0.63-0.85 of its light (tests/recon/test_do_no_harm.py; README of
  tools/results/real-data, "The clipped pixels' own light"). Applied locally first, so that a wrong edge does not dim a
  right core: each clipped pixel's excess is multiplied by the smallest headroom min(1, slack / (P * E))
  of the unclipped pixels within LOCAL_BOUND_PX of it, LOCAL_BOUND_ITERATIONS rounds; then one scale per
  cluster and channel makes the bound hold exactly. The window holds the shipped DOE's ring (3-4 px out; a
  3 px window missed it, so one over-lit ring pixel lowered a whole lamp: README of tools/results/real-data,
  "A local bound that reaches the DOE's ring"). Light that lands where only a lamp's nearest pixels are
  within the window of it (a 4 px lamp whose ring lies LOCAL_BOUND_PX + 3 = 8 px out; long streaks) is
  charged to those pixels alone: a small lamp proposed too bright can end below the truth (toward the frame,
  never above it; tests/recon/test_do_no_harm.py, known failure).
  Charging each pixel over its own PSF footprint, or the smallest change that satisfies the frame, fixed that
  but kept a too-bright edge around a right core (README of tools/results/real-data, "The judge alone"). A
  cluster whose light reaches fewer than MIN_WITNESS_PIXELS unclipped pixels (a frame that is all white) has
  no witness: the frame is kept.
- Defects. A pixel that clipped received at least white, and light on it reaches its neighbours through the
  PSF: a clipped speck (at most DEFECT_MAX_PIXELS pixels, 8-connected) that no non-negative light on its own
  pixels can make clip without sending some unclipped pixel within LOCAL_BOUND_PX more than it recorded beyond
  the allowance is a sensor defect - a hot pixel reads white without light (a small linear programme per speck
  and channel, :func:`_defects`). It keeps the clip level (no excess) and sends no own light (B = 0 there) in
  the bound and the evidence. Charged at white it over-explained its dark neighbours, and a lamp 12-30 px away
  whose spill reached them was cut to 0.47-1.0 of an exact proposal per channel (0.995 without the hot pixel;
  tests/recon/test_do_no_harm.py; tools/results/real-data/hot-pixel). Only where the ground is darker than the
  PSF's share for a nearest neighbour (0.05-0.07 of white, shipped DOE) can a hot pixel be told from light; a
  point whose neighbours clip from its spill is light (charging each of them at white called real lamps at
  14-17 x white defects). Only specks: a larger blob the PSF over-explains is a calibration error whose edge the
  bound must keep charging.
  The test refutes only light PSF_ERROR_FACTOR times what a pixel recorded with its allowance: through the
  demo's calibrated PSF (L1 4-6 % from the design) real lights of a dot grid needed 1.67-1.78 x to be explained
  and were called defects at 1 x. A pixel reading 0 beside a lamp (a dead pixel) is not handled: its slack is
  the noise allowance and the exact per-cluster scale, a minimum over pixels, keeps 0.04-0.92 of a lamp 5-26 px
  from it (a known limit, tests/recon/test_do_no_harm.py; a bound for any scene refutes it only within ~6 px,
  and not robustly to a calibrated PSF: tools/results/real-data/hot-pixel). A camera's known defects are
  repaired before the judge sees the frame (``hdrcam reconstruct --bad-pixels``, hdrcam.io.bad_pixels): the
  lamp 3-20 px from a listed dead pixel keeps 0.97-0.995 of its light.
- Evidence. The bound cannot see a highlight barely above the clip level: the lens core blurs the
  highlight's own edge below the clip level, and the unrecorded light of that edge is as large as a small
  excess's. The frame re-imaged from its own pixels tells them apart as far as the PSF allows: with
  A(v) = v - P * (v 1_U) (U: unclipped), A(y - P * B) = A(P * H_U) + A(P * E) where B is right. On the unclipped
  pixels EVIDENCE_INNER_PX..evidence_outer_px(PSF) from the cluster, A(y - P * B) is fitted by
  a A(P * E_proposed) + b A(P * D) + c, D = the most light the unclipped edge band can hide (y (1/P0 - 1),
  P0 the PSF's centre value), least squares. The ring starts EVIDENCE_INNER_PX beyond the highlight's bright
  edge - the cluster's clipped pixels with the unclipped pixels at NEAR_WHITE or above (in some channel)
  joined to them - not beyond its clipped pixels alone: a highlight barely above the clip level records its
  own pixels a few deep below white (where the lens core and the DOE's ring send more than 1 - 1/1.05 of their
  light past its edge, a disc at 1.05 clips only inside), and their unknown light dwarfs its streaks (such a
  disc on a 0.25-0.4 ramp: 214 unclipped blue pixels of its own, fitted as 28 x its true streaks at z 5;
  tests/recon/test_do_no_harm.py; tools/results/real-data/README.md, "A barely clipped highlight's own edge").
  Its significance z = a / s, s the standard error of a from the residual variance (at least the noise's) x
  TEXTURE_CORRELATION; where the excess's light and the edge's are alike (a weak DOE, a small excess), z is
  small: fall back. The kept share is
  (a + TEXTURE_SD_ALLOWANCE s_T) (1 - (Z_MIN / z)^2) for z > Z_MIN (at most 1), else 0, where s_T is the
  standard error from the residual variance beyond the noise's: the unclipped scene's own residual under A,
  A(P * H_U), is not noise but texture correlated with the streaks (2-5 x their light in norm around night
  windows), and it biases a both ways - the truth itself proposed fits a = 0.4-2.2, up to 20 s_T below 1 on
  dev night scenes (light-weighted 95th percentile 17). On a flat or noise-limited surround s_T = 0 and a
  stands (a lamp proposed 4 x too bright is cut to its truth); on a textured one the amount is left to the
  upper bound and the evidence decides whether the streaks show the light (tools/results/real-data/README.md,
  "The amount trusted only as far as the texture allows"). z asks whether the ring shows some light, not
  whether it shows the proposed amount: where the amplitude's standard error s exceeds MAX_AMPLITUDE_ERROR
  proposals - the proposed light's streaks lie that far below what the ring can resolve - the channel keeps
  nothing. A sky clipped in blue only, its truth 1.01 there, proposed at 1.035 fitted a = 1043 +- 230 (the truth
  proposed: 1123 +- 208): the fit read the sky's own gradient, and keeping the proposal cost the photograph
  0.18-0.39 dB against its 90 dB capture (tools/results/real-data/resolvable-evidence). The fit runs per
  channel; the cluster keeps the mean of the three shares in every channel: a highlight is one source seen in
  three bands, and a share per channel turned the noise of three fits into a colour (white lamps kept as
  (1, 29, 26): cyan cores; tools/results/real-data/README.md, "One evidence share per cluster").
- Shape. The frame constrains how much light a blob sends out, not how it is spread inside it: each pixel's
  excess is capped at SHAPE_CAP times its blob's mean excess (per channel, blobs = 8-connected clipped
  pixels), since a misplaced peak (50-100 where the truth is 1.5) costs far more than a flatter fill. A
  cluster whose evidence is strong (z >= STRONG_EVIDENCE_Z in some channel: its streaks confirm its light
  beyond doubt, as a lamp's do) and does not refute the amount (its evidence share - of the excess the upper
  bound left, with the texture's allowance above - is at least STRONG_EVIDENCE_SHARE in every channel; on a
  textured surround that holds for a proposal a few times too bright too) keeps the proposed shape: a lamp's
  core lies far above its blob's mean, and the cap cost night scenes most of the judge's loss; a proposal the
  evidence had to cut is wrong somewhere, and its peaks are capped - also a true lamp proposed a few times too
  bright whose bound and evidence cut it unevenly across channels (a 400 x white core proposed 3 x too bright
  ends near 35 instead of 415; tools/results/real-data/README.md, "Strong streak evidence lifts the shape cap",
  "The exemption only where the evidence also confirms the amount").

A clipped pixel deep inside a large clipped region sends no light to any unclipped pixel: only the evidence
of its cluster's edge and the network's prior (trained on real photographs, hdrcam.data.scenes) decide it.
The confidence map is the share of the proposed excess that was kept (1 where nothing clipped or nothing
was proposed). Measured against simpler judges (a planar-background streak fit, one scale per cluster, no
evidence) in tools/results/real-data/README.md.
"""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import torch
from scipy.optimize import linprog

from hdrcam.recon.tiling import CLIP_LEVEL, clipped_clusters
from hdrcam.sensor import fft_convolve, fft_shape, psf_spectrum, without_fft_round_off

K_SIGMA = 3.0  # noise allowance of the upper bound, in standard deviations
TOLERANCE = 0.002  # relative frame units: ADC steps, PSF calibration error
LOCAL_BOUND_PX = 5  # a clipped pixel answers for the unclipped pixels this close (the shipped DOE's ring + 1)
LOCAL_BOUND_ITERATIONS = 3
EVIDENCE_INNER_PX = 2  # the lens core: a highlight's own edge blurs this far (evidence starts beyond)
NEAR_WHITE = 0.9  # an unclipped pixel this bright, joined to a cluster, is its highlight's own edge ("Evidence")
EVIDENCE_ENERGY = 0.99  # the DOE's spill is read as far from the cluster as the PSF holds this share of its light
Z_MIN = 3.0  # evidence this many standard deviations above zero is kept at (1 - (Z_MIN / z)^2) of its amount
TEXTURE_CORRELATION = 4.0  # neighbouring residuals are correlated (texture, PSF): variance x this
MAX_AMPLITUDE_ERROR = 64.0  # evidence whose amount's standard error exceeds this many proposals resolves none of it
TEXTURE_SD_ALLOWANCE = 16.0  # the amount is trusted to within this many standard errors of the texture residual
MIN_FIT_PIXELS = 8  # fewer unclipped pixels in the evidence ring: no evidence, the frame is kept
MIN_WITNESS_PIXELS = 8  # a cluster whose light reaches fewer unclipped pixels has no evidence: the frame is kept
SHAPE_CAP = 4.0  # a pixel's excess is at most this multiple of its blob's mean excess
STRONG_EVIDENCE_Z = 20.0  # a cluster with evidence this significant in some channel is exempt from the shape cap
STRONG_EVIDENCE_SHARE = 0.8  # ... if its evidence share (of the bounded excess) is at least this in every channel
FALLEN_BACK_SHARE = 0.5  # a clipped pixel that kept less than this share of its proposed excess fell back
DEFECT_MAX_PIXELS = 4  # a clipped blob this small that no light through the PSF explains is a defect ("Defects")
PSF_ERROR_FACTOR = 3.0  # the defect test refutes only light this many times what a pixel recorded (with its
# allowance): a calibrated PSF's near shares are off by up to 1.78 x on the demo, hot pixels exceed 4 x


@dataclasses.dataclass(frozen=True)
class NoiseModel:
    """Shot + read noise of the frame, in electrons at the full well (relative value 1)."""

    full_well_e: float = 25000.0
    read_noise_e: float = 4.0

    def sigma(self, relative: np.ndarray) -> np.ndarray:
        """Standard deviation (relative units) of a pixel that recorded ``relative``."""
        return np.sqrt(np.clip(relative, 0.0, None) * self.full_well_e + self.read_noise_e ** 2) / self.full_well_e


@dataclasses.dataclass
class ConsistencyReport:
    clusters: int
    proposed_excess: float  # sum of the estimate's excess over 1 on clipped channels (relative radiance x pixels)
    kept_excess: float  # what the judged estimate keeps of it (after the shape cap)
    clipped_pixels: int
    fallen_back_pixels: int  # clipped pixels that kept less than FALLEN_BACK_SHARE of their proposed excess
    # H x W bool: clipped pixels of the clusters whose streak evidence did not refute the proposal (z >=
    # STRONG_EVIDENCE_Z, shares >= STRONG_EVIDENCE_SHARE: exempt from the shape cap); None where not recorded
    confirmed: np.ndarray | None = dataclasses.field(default=None, compare=False, repr=False)
    # H x W bool: clipped pixels of the clusters whose streaks show their proposed light beyond doubt (z >=
    # STRONG_EVIDENCE_Z in some channel), whatever share of it the evidence kept; None where not recorded
    strong_evidence: np.ndarray | None = dataclasses.field(default=None, compare=False, repr=False)
    defect_pixels: int = 0  # clipped pixels no light explains, kept at the clip level (module docstring, "Defects")

    @property
    def fallback_fraction(self) -> float:
        """Share of the proposed highlight excess the frame did not support (0: all kept, 1: the frame)."""
        return 1.0 - self.kept_excess / self.proposed_excess if self.proposed_excess > 0 else 0.0

    def summary(self) -> str:
        if not self.clusters:
            return "consistency: no clipped pixel"
        defects = (f"; {self.defect_pixels} clipped pixels no light can explain (hot pixels?) kept at white"
                   if self.defect_pixels else "")
        return (f"consistency: {self.clusters} clusters, kept {100 * (1 - self.fallback_fraction):.0f} % of the "
                f"proposed highlight excess; {self.fallen_back_pixels} of {self.clipped_pixels} clipped pixels "
                f"fell back towards the frame{defects}")


def make_consistent(frame: np.ndarray, estimate: np.ndarray, psf: np.ndarray, *, noise: NoiseModel = NoiseModel()
                    ) -> tuple[np.ndarray, np.ndarray, ConsistencyReport]:
    """H x W x 3 frame in [0, 1], an H x W x 3 HDR estimate (relative radiance) and the (3, k, k) unit-sum PSF
    -> (the estimate on clipped channels, bounded as the module docstring says, the frame elsewhere;
    H x W confidence in [0, 1]: the kept share on clipped pixels, 1 elsewhere; the report).

    Unclipped pixels are returned as the frame: subtract the highlights' spill afterwards."""
    return judge_estimates(frame, [estimate], psf, noise=noise)[0]


def judge_estimates(frame: np.ndarray, estimates: list[np.ndarray], psf: np.ndarray, *,
                    noise: NoiseModel = NoiseModel()) -> list[tuple[np.ndarray, np.ndarray, ConsistencyReport]]:
    """:func:`make_consistent` of each of several estimates of one frame: what the frame alone says of each
    cluster (its crops, unclipped pixels, noise, bright edge and the light its edge band can hide) is found
    once for all of them."""
    clipped_channels = frame >= CLIP_LEVEL
    clipped = clipped_channels.any(axis=-1)
    kernel = _Kernel(psf)
    views = [_ClusterView.of(frame, clipped_channels, crop, own, psf, kernel, noise)
             for crop, own in clipped_clusters(clipped, psf.shape[-1] // 2)] if clipped.any() else []
    return [_judged(frame, estimate, clipped_channels, views, kernel, evidence_outer_px(psf)) for estimate in estimates]


@dataclasses.dataclass
class _ClusterView:
    """What the frame alone says of one cluster of clipped pixels, whatever estimate is judged."""

    crop: tuple[slice, slice]  # the cluster grown by the PSF radius
    own: np.ndarray  # the crop's bool: the cluster's own clipped pixels
    region: tuple[slice, slice]  # the crop grown by two PSF radii: light from that far can matter
    inner: tuple[slice, slice]  # where the crop lies in the region
    unclipped: np.ndarray  # the region's unclipped channels
    sigma: np.ndarray  # the frame's noise on the crop
    nuisance: np.ndarray  # A(P * D) on the crop: the light the edge band can hide, beyond re-imaging
    edge: np.ndarray  # the crop's bool: the highlight with its own bright edge
    defect: np.ndarray  # the region's bool: clipped specks the frame refutes as light (module docstring, "Defects")

    @classmethod
    def of(cls, frame: np.ndarray, clipped_channels: np.ndarray, crop: tuple[slice, slice], own: np.ndarray,
           psf: np.ndarray, kernel: _Kernel, noise: NoiseModel) -> "_ClusterView":
        region, inner = _grown(crop, 2 * (psf.shape[-1] // 2), frame.shape[:2])
        unclipped = ~clipped_channels[region]
        band = _convolve(_edge_deficit_bound(frame[region], clipped_channels[region], psf), kernel)
        return cls(crop, own, region, inner, unclipped, noise.sigma(frame[crop]),
                   _beyond_reimaged(band, unclipped, kernel)[inner], _bright_edge(frame[crop], own),
                   _defects(frame[region], clipped_channels[region], kernel, noise))


def _judged(frame: np.ndarray, estimate: np.ndarray, clipped_channels: np.ndarray, views: list[_ClusterView],
            kernel: _Kernel, outer_px: int) -> tuple[np.ndarray, np.ndarray, ConsistencyReport]:
    """One estimate made consistent with the frame (:func:`make_consistent`), its clusters' ``views`` given."""
    clipped = clipped_channels.any(axis=-1)
    at = np.nonzero(clipped)  # the pixels a judgement can change: work on them, not the frame (24 MP: seconds)
    clipped_at = clipped_channels[at]
    floored_at = np.where(clipped_at, np.maximum(estimate[at], 1.0), frame[at]).astype(np.float32)
    output = frame.astype(np.float32)
    output[at] = floored_at
    confidence = np.ones(frame.shape[:2], np.float32)
    if not clipped_at.any():
        return output, confidence, ConsistencyReport(0, 0.0, 0.0, 0, 0, np.zeros(clipped.shape, bool),
                                                     np.zeros(clipped.shape, bool))
    proposed = 0.0
    defect_pixels = 0
    strong = np.zeros(clipped.shape, bool)  # clipped pixels of clusters with strong evidence
    confirmed = np.zeros(clipped.shape, bool)  # ... that also confirms the amount: shape kept
    for view in views:
        crop, own, region, inner, unclipped = view.crop, view.own, view.region, view.inner, view.unclipped
        defect = view.defect[inner] & own
        defect_pixels += int(defect.sum())
        mine = clipped_channels[crop] & (own & ~defect)[..., None]
        excess = np.where(mine, output[crop] - 1.0, 0.0).astype(np.float32)  # floored: no other cluster writes here
        own_light = np.where(clipped_channels[region] & ~view.defect[..., None], np.clip(estimate[region], 0.0, 1.0),
                             0.0).astype(np.float32)  # B
        explained = frame[region] - _convolve(own_light, kernel)  # y - P * B
        slack = np.maximum(explained[inner], 0.0) + K_SIGMA * view.sigma + TOLERANCE
        spill = np.zeros_like(explained)
        kept_excess, spill[inner] = _bounded_excess(slack, unclipped[inner], excess, kernel)
        shares, significance = _evidence_shares(_beyond_reimaged(explained, unclipped, kernel)[inner],
                                                _beyond_reimaged(spill, unclipped, kernel)[inner],
                                                view.nuisance, unclipped[inner], own, view.edge, view.sigma,
                                                outer_px)
        # one source in three bands: one share keeps its colour - the mean over the channels that hold its excess
        # (a red light's green and blue, with nothing to fit, would lift a red share of 0 to 2/3)
        proposed_channels = kept_excess.sum(axis=(0, 1)) > 0
        shares = np.full_like(shares, shares[proposed_channels].mean() if proposed_channels.any() else 0.0)
        kept_excess = kept_excess * shares
        if significance >= STRONG_EVIDENCE_Z:
            strong[crop] |= own
            if shares.min() >= STRONG_EVIDENCE_SHARE:
                confirmed[crop] |= own
        defect_channels = defect[..., None] & clipped_channels[crop]
        proposed += float(excess.sum()) + float(np.where(defect_channels, output[crop] - 1.0, 0.0).sum())
        output[crop] = np.where(mine, 1.0 + kept_excess, np.where(defect_channels, 1.0, output[crop]))
    _cap_shapes(output, at, clipped_at, clipped, confirmed[at])
    excess_proposed = np.where(clipped_at, floored_at - 1.0, 0.0)
    excess_kept = np.where(clipped_at, output[at] - 1.0, 0.0)  # after the shape cap
    kept = float(excess_kept.sum())
    share = np.where(excess_proposed > 0, excess_kept / np.maximum(excess_proposed, 1e-12), 1.0).min(axis=-1)
    confidence[at] = np.clip(share, 0.0, 1.0)
    fallen_back = int((confidence[at] < FALLEN_BACK_SHARE).sum())
    return output, confidence, ConsistencyReport(len(views), proposed, kept, int(clipped.sum()), fallen_back,
                                                 confirmed, strong, defect_pixels)


def _bounded_excess(slack: np.ndarray, unclipped: np.ndarray, excess: np.ndarray, kernel: _Kernel
                    ) -> tuple[np.ndarray, np.ndarray]:
    """One cluster's crop (H x W x 3 each) -> (its excess lowered where its re-imaged light would exceed the
    frame's slack, locally first, then exactly (module docstring), nowhere raised; that excess's spill P * E)."""
    bounded = excess.copy()
    window = np.ones((2 * LOCAL_BOUND_PX + 1,) * 2, np.uint8)
    for _ in range(LOCAL_BOUND_ITERATIONS):
        headroom = _headroom(slack, unclipped, _convolve(bounded, kernel))
        for channel in range(3):
            bounded[..., channel] *= cv2.erode(headroom[..., channel], window, borderType=cv2.BORDER_REPLICATE)
    spill = _convolve(bounded, kernel)
    witnesses = (unclipped & (spill > 0)).sum(axis=(0, 1))
    scale = np.where(witnesses >= MIN_WITNESS_PIXELS, _headroom(slack, unclipped, spill).min(axis=(0, 1)), 0.0)
    return bounded * scale, spill * scale  # P * (s E) = s (P * E): no second convolution


def _defects(frame: np.ndarray, clipped_channels: np.ndarray, kernel: _Kernel, noise: NoiseModel) -> np.ndarray:
    """H x W bool of an H x W x 3 ``frame`` crop: the pixels of its clipped specks (8-connected blobs of at most
    DEFECT_MAX_PIXELS, not touching the crop's border, where a larger blob may be cut) that no non-negative light
    on the speck explains (module docstring, "Defects"): in some channel c it clipped in, no H >= 0 on its pixels
    p gives sum_p H_p P_c(q - p) >= CLIP_LEVEL - o(q) on its clipped pixels q - o the light the rest of the frame
    sends there, P * y with every speck left out - while sum_p H_p P_c(x - p) <= y(x) + K_SIGMA sigma + TOLERANCE
    on the unclipped pixels x within LOCAL_BOUND_PX (a linear programme of at most DEFECT_MAX_PIXELS unknowns),
    the right side times PSF_ERROR_FACTOR."""
    clipped = clipped_channels.any(axis=-1)
    _, labels, stats, _ = cv2.connectedComponentsWithStats(clipped.astype(np.uint8), connectivity=8)
    lefts, tops = stats[:, cv2.CC_STAT_LEFT], stats[:, cv2.CC_STAT_TOP]
    inside = ((lefts > LOCAL_BOUND_PX) & (tops > LOCAL_BOUND_PX)
              & (lefts + stats[:, cv2.CC_STAT_WIDTH] + LOCAL_BOUND_PX < clipped.shape[1])
              & (tops + stats[:, cv2.CC_STAT_HEIGHT] + LOCAL_BOUND_PX < clipped.shape[0]))
    is_speck = (stats[:, cv2.CC_STAT_AREA] <= DEFECT_MAX_PIXELS) & inside
    is_speck[0] = False  # the background
    defects = np.zeros(clipped.shape, bool)
    if not is_speck.any():
        return defects
    elsewhere = np.where(is_speck[labels][..., None], 0.0, frame)  # o(q) leaves every speck out
    psf = kernel.tensor.numpy().astype(np.float64)
    for label in np.flatnonzero(is_speck):
        top, left = tops[label], lefts[label]
        height, width = stats[label, cv2.CC_STAT_HEIGHT], stats[label, cv2.CC_STAT_WIDTH]
        rows, columns = np.nonzero(labels[top:top + height, left:left + width] == label)
        rows, columns = rows + top, columns + left
        window = (slice(top - LOCAL_BOUND_PX, top + height + LOCAL_BOUND_PX),
                  slice(left - LOCAL_BOUND_PX, left + width + LOCAL_BOUND_PX))
        needed = CLIP_LEVEL - np.array([_received(elsewhere, row, column, kernel)
                                        for row, column in zip(rows, columns)])  # (speck pixels, 3)
        most_received = PSF_ERROR_FACTOR * (frame[window] + K_SIGMA * noise.sigma(frame[window]) + TOLERANCE)
        for channel in np.flatnonzero(clipped_channels[rows, columns].any(axis=0)):
            lit = clipped_channels[rows, columns, channel]
            unclipped = np.nonzero(~clipped_channels[window][..., channel])
            if not _light_explains(psf[channel], (rows, columns), lit, needed[lit, channel],
                                   (unclipped[0] + window[0].start, unclipped[1] + window[1].start),
                                   most_received[..., channel][unclipped]):
                defects[rows, columns] = True
                break
    return defects


def _received(image: np.ndarray, row: int, column: int, kernel: _Kernel) -> np.ndarray:
    """(3,): (P * image) at one pixel, the PSF's reach cut at the image's border."""
    psf = kernel.tensor.numpy()
    radius = psf.shape[-1] // 2
    top, bottom = max(row - radius, 0), min(row + radius + 1, image.shape[0])
    left, right = max(column - radius, 0), min(column + radius + 1, image.shape[1])
    # (P * image)(q) = sum_x P(q - x) image(x): the PSF flipped over the window
    flipped = psf[:, ::-1, ::-1][:, top - row + radius:bottom - row + radius,
                                 left - column + radius:right - column + radius]
    return np.einsum("chw,hwc->c", flipped, image[top:bottom, left:right])


def _transfer(psf: np.ndarray, targets: tuple[np.ndarray, np.ndarray], sources: tuple[np.ndarray, np.ndarray]
              ) -> np.ndarray:
    """(targets, sources): the share of its light each source pixel sends each target pixel through one channel's
    (k, k) PSF, P(target - source); pixels as (rows, columns)."""
    radius = psf.shape[-1] // 2
    offset_rows = targets[0][:, None] - sources[0][None, :] + radius
    offset_columns = targets[1][:, None] - sources[1][None, :] + radius
    within = ((offset_rows >= 0) & (offset_rows <= 2 * radius) & (offset_columns >= 0)
              & (offset_columns <= 2 * radius))
    return np.where(within, psf[offset_rows.clip(0, 2 * radius), offset_columns.clip(0, 2 * radius)], 0.0)


def _light_explains(psf: np.ndarray, sources: tuple[np.ndarray, np.ndarray], lit: np.ndarray, needed: np.ndarray,
                    unclipped: tuple[np.ndarray, np.ndarray], most_received: np.ndarray) -> bool:
    """Whether some light H >= 0 on the n ``sources`` (rows, columns), through one channel's PSF, gives each of
    the ``lit`` ones (n bool) at least ``needed`` and each ``unclipped`` pixel at most ``most_received``.
    Tried first without a solver: each lit pixel alone lighting itself to the most any of them needs (more light
    than needed; on a bright ground, where specks of noise clip, it already fits)."""
    at_least = _transfer(psf, (sources[0][lit], sources[1][lit]), sources)
    at_most = _transfer(psf, unclipped, sources)
    generous = np.where(lit, needed.max(initial=0.0) / psf[psf.shape[-1] // 2, psf.shape[-1] // 2], 0.0)
    if np.all(at_least @ generous >= needed) and np.all(at_most @ generous <= most_received):
        return True
    result = linprog(np.zeros(len(lit)), A_ub=np.vstack([-at_least, at_most]),
                     b_ub=np.concatenate([-needed, most_received]), bounds=(0, None), method="highs")
    return result.status != 2  # 2: infeasible


def _grown(crop: tuple[slice, slice], by_px: int, shape: tuple[int, int]) -> tuple[tuple[slice, slice],
                                                                                 tuple[slice, slice]]:
    """``crop`` grown by ``by_px`` within an image of ``shape``, and where ``crop`` lies inside it."""
    rows, columns = crop
    top, left = max(rows.start - by_px, 0), max(columns.start - by_px, 0)
    bottom, right = min(rows.stop + by_px, shape[0]), min(columns.stop + by_px, shape[1])
    return ((slice(top, bottom), slice(left, right)),
            (slice(rows.start - top, rows.stop - top), slice(columns.start - left, columns.stop - left)))


def _edge_deficit_bound(frame: np.ndarray, clipped_channels: np.ndarray, psf: np.ndarray) -> np.ndarray:
    """The most light the unclipped pixels within EVIDENCE_INNER_PX of a clipped pixel can hold beyond what
    they recorded: a highlight's own edge, blurred below the clip level by the lens core. A pixel keeps the
    share P0 (the PSF's centre value) of its light, so its radiance is at most y / P0: the deficit is at most
    y (1 / P0 - 1). H x W x 3, zero elsewhere."""
    centre = psf[:, psf.shape[1] // 2, psf.shape[2] // 2].astype(np.float32)
    window = np.ones((2 * EVIDENCE_INNER_PX + 1,) * 2, np.uint8)
    near = np.stack([cv2.dilate(clipped_channels[..., c].astype(np.uint8), window) > 0 for c in range(3)], axis=-1)
    band = near & ~clipped_channels
    return np.where(band, frame * (1.0 / np.maximum(centre, 1e-3) - 1.0), 0.0).astype(np.float32)


def _beyond_reimaged(light: np.ndarray, unclipped: np.ndarray, kernel: _Kernel) -> np.ndarray:
    """A(v) = v - P * (v on unclipped pixels): what a light map holds beyond what re-imaging the frame's own
    unclipped pixels through the PSF accounts for (the evidence's operator, see _evidence_shares)."""
    return light - _convolve(np.where(unclipped, light, 0.0).astype(np.float32), kernel)


def evidence_outer_px(psf: np.ndarray) -> int:
    """Half-width (px) of the smallest square about the PSF's axis that holds EVIDENCE_ENERGY of every channel's
    light (at least EVIDENCE_INNER_PX + 1): a compact ring is read close by, long streaks far out."""
    centre = psf.shape[-1] // 2
    totals = psf.sum(axis=(-2, -1))
    for half_width in range(EVIDENCE_INNER_PX + 1, centre + 1):
        window = psf[:, centre - half_width:centre + half_width + 1, centre - half_width:centre + half_width + 1]
        if np.all(window.sum(axis=(-2, -1)) >= EVIDENCE_ENERGY * totals):
            return half_width
    return centre


def _bright_edge(frame: np.ndarray, own: np.ndarray) -> np.ndarray:
    """A cluster's clipped pixels ``own`` (H x W bool, on its crop of ``frame``) with the pixels at NEAR_WHITE or
    above in some channel that are 8-connected to them: the highlight with its own bright edge."""
    bright = (frame >= NEAR_WHITE).any(axis=-1) | own
    _, labels = cv2.connectedComponents(bright.astype(np.uint8), connectivity=8)
    return np.isin(labels, np.unique(labels[own]))


def _evidence_shares(observed: np.ndarray, predicted: np.ndarray, nuisance: np.ndarray, unclipped: np.ndarray,
                     own: np.ndarray, edge: np.ndarray, sigma: np.ndarray, outer_px: int
                     ) -> tuple[np.ndarray, float]:
    """(3,) shares in [0, 1] of a cluster's excess that the light beyond its lens core supports (module
    docstring, "Evidence"), and the largest of the channels' significances z (-inf where no channel was fitted):
    ``observed`` = A(y - P * B), ``predicted`` = A(P * E), ``nuisance`` = A(P * D), H x W x 3 each on the
    cluster's crop; fitted on the unclipped pixels more than EVIDENCE_INNER_PX from ``edge`` (the highlight with
    its bright edge, _bright_edge) and at most ``outer_px`` from ``own`` (the cluster's clipped pixels).
    ``sigma``: the frame's noise there."""
    inner = cv2.dilate(edge.astype(np.uint8), np.ones((2 * EVIDENCE_INNER_PX + 1,) * 2, np.uint8)) > 0
    outer = cv2.dilate(own.astype(np.uint8), np.ones((2 * outer_px + 1,) * 2, np.uint8)) > 0
    shares = np.zeros(3, np.float32)  # no evidence, the frame kept: where no fit runs
    significance = -np.inf
    for channel in range(3):
        ring = outer & ~inner & unclipped[..., channel]
        signal = predicted[..., channel][ring].astype(np.float64)
        values = observed[..., channel][ring].astype(np.float64)
        if ring.sum() < MIN_FIT_PIXELS or float(signal @ signal) <= 0.0:
            continue  # no pixel beyond the lens core could see (or was sent) this channel's light
        design = np.stack([signal, nuisance[..., channel][ring].astype(np.float64), np.ones_like(signal)], axis=1)
        coefficients, amplitude_variance_factor = _least_squares(design, values)
        amplitude = float(coefficients[0])
        residual_variance = float(np.mean((values - design @ coefficients) ** 2))
        noise_variance = float(np.mean(sigma[..., channel][ring] ** 2))
        amplitude_variance_factor *= TEXTURE_CORRELATION
        amplitude_error = np.sqrt(max(amplitude_variance_factor * max(residual_variance, noise_variance), 1e-30))
        z = amplitude / amplitude_error
        texture_sd = np.sqrt(amplitude_variance_factor * max(residual_variance - noise_variance, 0.0))
        shares[channel] = min(1.0, (amplitude + TEXTURE_SD_ALLOWANCE * texture_sd) * (1.0 - (Z_MIN / z) ** 2)) \
            if z > Z_MIN and amplitude_error <= MAX_AMPLITUDE_ERROR else 0.0
        significance = max(significance, z)
    return shares, significance


def _least_squares(design: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, float]:
    """Least-squares coefficients of ``values`` on the columns of ``design`` (N x K), and (D^T D)^-1[0, 0], the
    first coefficient's variance per unit residual variance. The columns are scaled to unit norm first: a proposal
    whose streaks are 1e-7 of the ring's values (a channel clipped by a hair) otherwise fell below the
    pseudo-inverse's cut-off, which returned a variance 1e-16 of the true one - z = 1.5e9 for a fit of noise."""
    norms = np.linalg.norm(design, axis=0)
    norms[norms == 0.0] = 1.0
    scaled = design / norms
    coefficients, *_ = np.linalg.lstsq(scaled, values, rcond=None)
    return coefficients / norms, float(np.linalg.pinv(scaled.T @ scaled)[0, 0]) / float(norms[0]) ** 2


def _headroom(slack: np.ndarray, unclipped: np.ndarray, spill: np.ndarray) -> np.ndarray:
    """min(1, slack / spill) on unclipped pixels that the spill reaches, 1 elsewhere (``slack`` is positive: it
    holds the noise allowance)."""
    reached = unclipped & (spill > 0)
    headroom = np.divide(slack, spill, out=np.ones_like(spill), where=reached)
    return np.clip(headroom, 0.0, 1.0, out=headroom)


def _cap_shapes(estimate: np.ndarray, at: tuple[np.ndarray, np.ndarray], clipped_at: np.ndarray,
                clipped: np.ndarray, exempt_at: np.ndarray) -> None:
    """Each clipped channel's excess over 1 in ``estimate`` (H x W x 3, changed in place) capped at SHAPE_CAP
    times its blob's mean excess in that channel, except on exempt pixels. ``at``: the clipped pixels' (rows,
    columns), ``clipped_at`` (n x 3) which of their channels clipped, ``exempt_at`` (n) which are exempt;
    ``clipped``: H x W bool, whose 8-connected blobs are the blobs."""
    blob_count, labels = cv2.connectedComponents(clipped.astype(np.uint8), connectivity=8)
    index = labels[at]
    values = estimate[at]
    for channel in range(3):
        mine = clipped_at[:, channel]
        excess = np.where(mine, values[:, channel] - 1.0, 0.0)
        pixels = np.bincount(index, weights=mine.astype(np.float64), minlength=blob_count)
        mean = np.bincount(index, weights=excess, minlength=blob_count) / np.maximum(pixels, 1.0)
        limit = (SHAPE_CAP * mean)[index]
        values[:, channel] = np.where(mine & ~exempt_at, 1.0 + np.minimum(excess, limit), values[:, channel])
    estimate[at] = values


class _Kernel:
    """The judge's (3, k, k) PSF as a tensor, with its spectra at the FFT shapes of the last cluster's arrays (its
    crop and its grown region: nine convolutions per cluster share two spectra)."""

    SHAPES_KEPT = 2

    def __init__(self, psf: np.ndarray):
        self.tensor = torch.from_numpy(np.ascontiguousarray(psf, np.float32))
        self._spectra: dict[tuple[int, int], torch.Tensor] = {}

    def spectrum(self, image_shape: tuple[int, int]) -> torch.Tensor:
        shape = fft_shape(image_shape, self.tensor.shape[-2:])
        if shape not in self._spectra:
            if len(self._spectra) >= self.SHAPES_KEPT:
                self._spectra.clear()
            self._spectra[shape] = psf_spectrum(self.tensor, shape)
        return self._spectra[shape]


def _convolve(image: np.ndarray, kernel: _Kernel) -> np.ndarray:
    """P * image (H x W x 3), without the FFT's round-off (hdrcam.sensor.without_fft_round_off): where a PSF sends
    no light (a Dirac pattern's tails), round-off of 1e-7 of the peak counted as witnesses and was fitted as
    evidence (a proposal of 200 kept at 67-200 for a light twice white)."""
    planes = torch.from_numpy(np.ascontiguousarray(image.transpose(2, 0, 1), np.float32))
    return without_fft_round_off(fft_convolve(planes, kernel.tensor, spectrum=kernel.spectrum(image.shape[:2]))
                                 ).numpy().transpose(1, 2, 0)
