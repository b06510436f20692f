"""Where inside a clipped blob its light sits, read from the streaks (paper Eq. 6 inverted where the network cannot).

The networks paint a clipped blob with its typical value and never place a sun: on the real validation
photographs 6-14 pixels at the protocol's 2^8 cap hold 65-89 % of the capture's error, inside blobs of
~4,000 clipped pixels the networks fill at 1.1-1.7 (tools/results/real-data/README.md, "Where the remaining gain
lies"). The sun's streaks say where it is: a DOE with long streaks puts 2-3 % of its light on pixels that did not
clip, at hundreds of sigma of signal.

Model. J is the estimate so far: the judged estimate on clipped pixels, the frame less the highlights' spill
elsewhere (hdrcam.recon.highlight_spill). Adding an excess d (relative radiance, the same in the three channels)
on a cluster's pixels clipped in every channel changes what J re-images onto the unclipped pixels U by

    A d = P * d - P * ((P * d) 1_U),

its own light less that of the spill the output then takes off the unclipped pixels (the frame there already
holds the streaks; leaving out the second term overstates the streaks' signal about four-fold with the A7
rank-1 DOE and the fit places a quarter of the light). d minimises

    1/2 sum_c sum_{x in W} (r_c(x) - (A d)_c(x))^2 / sigma_c(x)^2 + lambda sum d,     0 <= d <= 2^8 - J,

with r = y - P * J the light the frame holds beyond the estimate, W the unclipped pixels at least GUARD_PX from
a clipped one, sigma the camera's shot and read noise, and lambda = SPARSITY times the largest entry of the
data term's gradient at d = 0 (per cluster): only pixels whose streaks meet the residual at least SPARSITY as
well as the best one take light, so the excess gathers where the streaks point. Beside d, a uniform glow g >= 0
over the whole support, unpenalised, takes the light of a blob the estimate made too dim everywhere (a window,
not a sun); it explains the residual in the fit and is not added to the output. FISTA (Beck and Teboulle
2009): ITERATIONS steps of 1 / L, L from POWER_ITERATIONS power iterations (times LIPSCHITZ_MARGIN), g solved
exactly at each step. J is mirrored across the frame's border before it is re-imaged: the light a border pixel
received from outside the frame is otherwise missing from P * J and reads as streaks (a 24 % spread PSF near a
0.5 sky: 0.1 per pixel).

Three gates keep the fit to what it can tell. A PSF with less than MIN_FAR_SHARE of its light (weakest channel)
beyond TEXTURE_RING_PX from its centre is not fitted at all: its streaks end inside the ring around a blob where
the blob's own glow and the scene's edge dominate (the shipped `simulated` DOE: 0 %, Table 2's Dirac and
dual-peak 0.11 %; rank-1 1.5 %, star 1.4 %, free-form 3.1 %). A cluster whose residual on the ring (the pixels of
W within TEXTURE_RING_PX of its clipped pixels) exceeds MAX_RING_CHI2 per pixel and channel is left alone: the
scene's texture, which J's unclipped pixels (the frame less the spill, not the deconvolved scene) leave in the
residual, is there larger than the streaks (Table 2 rank-1 on the training photographs: 0.6-2.4 around the four
suns it places best, 5.7-31 around the photographs it harmed, but 0.85 around an overcast sky). A cluster whose
fitted glow exceeds MAX_GLOW gets no excess: the estimate lacks the blob's own light there, and the sparse part
turns it into spikes (the overcast sky: 3.0; the suns: 0; a synthetic 3 x 3 sun in a 10 px glow: 1.2).

The result is a proposal, not an answer: the frame's judge (hdrcam.recon.consistency) vets it as it vets a
network's. Measured (tools/results/placement/README.md): on the 35 training photographs through Table 2's rank-1
DOE it lifts kloppenheim_05, narrow_moonlit_road and noon_grass by 8.6-10.9 dB and moves nothing else; on the
validation split and the night scenes it changes nothing (every validation sun sits in a ring of 7.5-38 chi^2
per pixel, above MAX_RING_CHI2). It is therefore off by default: an option of reconstruct and evaluate.

Only what the frame needs is modelled: each cluster of clipped pixels (hdrcam.recon.tiling.clipped_clusters
with twice the PSF radius, A's reach) is fitted in its own crop, grown by a further PSF radius for P * J.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np
import torch

from hdrcam.recon.consistency import NoiseModel
from hdrcam.recon.stages import HIGHLIGHT_PEAK
from hdrcam.recon.tiling import CLIP_LEVEL, clipped_clusters, clipped_mask, within_px
from hdrcam.sensor import fft_convolve, fft_shape, psf_spectrum

SPARSITY = 0.05  # lambda as a share of the largest gradient entry at d = 0
ITERATIONS = 200
POWER_ITERATIONS = 20
LIPSCHITZ_MARGIN = 1.1
GUARD_PX = 8  # unclipped pixels this close to a clipped one are left out of the fit (their residual is the
# network's edge and the lens core's more than the streaks': 2 px cost brown_photostudio_06 -5.2 dB against -1.9)
MAX_GLOW = 2.0  # relative radiance: a cluster whose fitted glow exceeds it gets no excess (module docstring)
TEXTURE_RING_PX = 48  # the ring beyond GUARD_PX, this far from the cluster's clipped pixels, whose residual is judged
MAX_RING_CHI2 = 3.0  # per pixel and channel: above it the scene's texture, not noise, fills the residual
MIN_FAR_SHARE = 0.005  # of the PSF's light beyond TEXTURE_RING_PX (its weakest channel), below which nothing runs
MIN_CURVATURE = 1e-3  # of A^T W A (1 / relative radiance^2): below it the PSF shows the support's light nowhere
# W sees (A d is FFT round-off there, ~1e-9; the A7 rank-1 DOE on a sun's blob: 0.3-30)


@dataclasses.dataclass
class PlacementReport:
    clusters: int  # clusters holding pixels clipped in every channel (the fit's candidates)
    placed_px: int  # pixels given more than 1 (relative radiance) of excess
    placed_light: float  # the excess map summed (the same in each channel; relative radiance x px)
    seconds: float
    far_share: float  # of the PSF's light beyond TEXTURE_RING_PX (weakest channel)

    def summary(self) -> str:
        if self.far_share < MIN_FAR_SHARE:
            return (f"highlight placement: not run, the PSF puts {100 * self.far_share:.2f} % of its light beyond "
                    f"{TEXTURE_RING_PX} px (at least {100 * MIN_FAR_SHARE:.1f} % needed)")
        if not self.clusters:
            return "highlight placement: no pixel clipped in every channel"
        return (f"highlight placement: {self.placed_px} px given {self.placed_light:.0f} of light (before the "
                f"judge) in {self.clusters} clusters")


def place_highlights(frame: np.ndarray, estimate: np.ndarray, psf: np.ndarray, *,
                     noise: NoiseModel | None = None) -> tuple[np.ndarray, PlacementReport]:
    """H x W x 3 frame in [0, 1], the H x W x 3 estimate so far (relative radiance: judged on clipped pixels,
    the frame less the spill elsewhere), the (3, k, k) unit-sum PSF -> (the estimate with the fitted excess added
    on pixels clipped in every channel, at most 2^8; the report). The caller has the judge vet it."""
    started = time.perf_counter()
    noise = noise or NoiseModel()
    proposal = np.array(estimate, np.float32, copy=True)
    clipped = clipped_mask(frame)
    every = np.min(frame, axis=-1) >= CLIP_LEVEL
    share = far_share(psf)
    if share < MIN_FAR_SHARE:  # streaks that end inside the ring cannot be told from the glow
        return proposal, PlacementReport(0, 0, 0.0, time.perf_counter() - started, share)
    radius = psf.shape[-1] // 2
    kernel = torch.from_numpy(np.ascontiguousarray(psf, np.float32))
    clusters = placed_px = 0
    placed_light = 0.0
    for crop, own in clipped_clusters(clipped, 2 * radius):
        support = own & every[crop]
        if not support.any():
            continue
        clusters += 1
        excess = _fit_cluster(frame, estimate, clipped, crop, support, kernel, radius, noise)
        proposal[crop] = np.minimum(proposal[crop] + excess[..., None], HIGHLIGHT_PEAK)
        placed_px += int(np.count_nonzero(excess > 1.0))
        placed_light += float(excess.sum())
    return proposal, PlacementReport(clusters, placed_px, placed_light, time.perf_counter() - started, share)


def far_share(psf: np.ndarray) -> float:
    """The share of the (3, k, k) PSF's light beyond TEXTURE_RING_PX from its centre, in its weakest channel."""
    rows, columns = np.mgrid[:psf.shape[-2], :psf.shape[-1]]
    far = np.hypot(rows - psf.shape[-2] // 2, columns - psf.shape[-1] // 2) > TEXTURE_RING_PX
    totals = psf.reshape(psf.shape[0], -1).sum(axis=1)
    return float(np.min(psf[:, far].sum(axis=1) / np.where(totals > 0, totals, 1.0)))


def _fit_cluster(frame: np.ndarray, estimate: np.ndarray, clipped: np.ndarray, crop: tuple[slice, slice],
                 support: np.ndarray, kernel: torch.Tensor, radius: int, noise: NoiseModel) -> np.ndarray:
    """The excess d (crop's H x W, relative radiance) of one cluster (module docstring)."""
    rows, columns = crop
    height, width = frame.shape[:2]
    # J with the PSF radius of context around the crop: the frame's own pixels where it has them, mirrored
    # across its border where it does not
    top, bottom = max(rows.start - radius, 0), min(rows.stop + radius, height)
    left, right = max(columns.start - radius, 0), min(columns.stop + radius, width)
    pads = ((radius - (rows.start - top), radius - (bottom - rows.stop)),
            (radius - (columns.start - left), radius - (right - columns.stop)), (0, 0))
    context = _mirror_pad(estimate[top:bottom, left:right], pads)
    reimaged = fft_convolve(_planes(context), kernel)[:, radius:-radius, radius:-radius]
    observed = _planes(frame[crop])
    residual = observed - reimaged
    unclipped = torch.from_numpy(~clipped[crop]).to(torch.float32)
    near = within_px(clipped[crop], GUARD_PX)
    sigma = torch.from_numpy(noise.sigma(frame[crop]).astype(np.float32).transpose(2, 0, 1))
    weight = torch.from_numpy(~near).to(torch.float32) / sigma ** 2
    ring = ~near & within_px(clipped[crop], TEXTURE_RING_PX)
    if not ring.any() or float((weight * residual ** 2)[:, torch.from_numpy(ring)].mean()) > MAX_RING_CHI2:
        return np.zeros(support.shape, np.float32)  # textured surround (or none seen): streaks not told apart
    inside = torch.from_numpy(support).to(torch.float32)
    ceiling = torch.from_numpy((HIGHLIGHT_PEAK - estimate[crop].max(axis=-1)).clip(0.0, None).astype(np.float32))
    shape = fft_shape(tuple(support.shape), tuple(kernel.shape[-2:]))
    flipped = torch.flip(kernel, (-2, -1))
    forward_spectrum, adjoint_spectrum = psf_spectrum(kernel, shape), psf_spectrum(flipped, shape)

    def forward(excess: torch.Tensor) -> torch.Tensor:  # A d, (3, H, W)
        light = fft_convolve(excess.expand(3, -1, -1), kernel, spectrum=forward_spectrum)
        return light - fft_convolve(light * unclipped, kernel, spectrum=forward_spectrum)

    def adjoint(planes: torch.Tensor) -> torch.Tensor:  # A^T v on the support, (H, W)
        light = fft_convolve(planes, flipped, spectrum=adjoint_spectrum)
        return (light - fft_convolve(light * unclipped, flipped, spectrum=adjoint_spectrum)).sum(0) * inside

    gradient_at_zero = adjoint(weight * residual)
    threshold = SPARSITY * float(gradient_at_zero.max())
    if threshold <= 0.0:
        return np.zeros(support.shape, np.float32)  # the frame holds no light the estimate lacks
    lipschitz = _lipschitz(forward, adjoint, weight, inside)
    if lipschitz < MIN_CURVATURE:
        return np.zeros(support.shape, np.float32)  # the PSF sends none of the support's light where it is seen
    glow_light = forward(inside)  # A 1_S: the light of a uniform unit excess over the support
    glow_curvature = float((weight * glow_light ** 2).sum())
    excess, glow = torch.zeros_like(inside), 0.0
    momentum, step_weight = excess, 1.0
    for _ in range(ITERATIONS):
        unexplained = residual - forward(momentum)
        if glow_curvature > 0.0:
            glow = max(float((weight * glow_light * unexplained).sum()) / glow_curvature, 0.0)
        gradient = -adjoint(weight * (unexplained - glow * glow_light))
        following = torch.minimum((momentum - (gradient + threshold) / lipschitz).clamp(min=0.0),
                                  (ceiling - glow).clamp(min=0.0)) * inside
        next_weight = (1.0 + (1.0 + 4.0 * step_weight ** 2) ** 0.5) / 2.0
        momentum = following + (step_weight - 1.0) / next_weight * (following - excess)
        excess, step_weight = following, next_weight
    if glow > MAX_GLOW:
        return np.zeros(support.shape, np.float32)  # the blob's own missing light, not a point's: no evidence
    return excess.numpy()


def _lipschitz(forward, adjoint, weight: torch.Tensor, inside: torch.Tensor) -> float:
    """LIPSCHITZ_MARGIN x the largest eigenvalue of A^T W A on the support, by power iterations."""
    vector = torch.rand(inside.shape, generator=torch.Generator().manual_seed(0)) * inside
    largest = 0.0
    for _ in range(POWER_ITERATIONS):
        vector = adjoint(weight * forward(vector))
        largest = float(vector.norm())
        if largest < MIN_CURVATURE:
            return 0.0
        vector = vector / largest
    return LIPSCHITZ_MARGIN * largest


def _mirror_pad(image: np.ndarray, pads: tuple) -> np.ndarray:
    """``image`` padded by mirroring (edge repeat where it is too small to mirror)."""
    if not any(before or after for before, after in pads):
        return image
    small = any(size <= max(before, after) for size, (before, after) in zip(image.shape, pads))
    return np.pad(image, pads, mode="edge" if small else "reflect")


def _planes(image: np.ndarray) -> torch.Tensor:
    return torch.from_numpy(np.ascontiguousarray(image.transpose(2, 0, 1), np.float32))
