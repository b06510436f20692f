"""`hdrcam reconstruct` on a RAW file reads a highlight's clipped green and blue from its red, through the file's
as-shot neutral (hdrcam.recon.colour_fill), and says how many samples it raised."""

from __future__ import annotations

import json

import cv2
import numpy as np

from hdrcam.cli import main
from hdrcam.io.exr import read_exr
from hdrcam.io.ldr_frame import read_ldr_capture
from tests.io.realistic_dng import write_dng

NEUTRAL = np.array([0.5, 1.0, 0.7])  # write_dng's AsShotNeutral: a grey surface in the file's camera RGB
BLACK_DN, WHITE_DN = 512, 16383


def _white_disc_dng(path, size_px=96, radius_px=16, disc=1.8, ground=0.4):
    """A disc of white light at ``disc`` x green's white on a grey ground, in camera RGB, through a lens that blurs
    it by a Gaussian of 1.5 px: green and blue clip, red reads 0.9; RGGB mosaic with 0.3 % noise (a noiseless
    plateau would read as a sensor's clip pile-up)."""
    rows, cols = np.mgrid[:size_px, :size_px]
    inside = (rows - size_px / 2 + 0.5) ** 2 + (cols - size_px / 2 + 0.5) ** 2 <= radius_px ** 2
    rgb = cv2.GaussianBlur(np.where(inside[..., None], disc, ground) * NEUTRAL, (0, 0), 1.5)
    channel = np.array([[0, 1], [1, 2]])[rows % 2, cols % 2]
    value = np.take_along_axis(rgb, channel[..., None], axis=-1)[..., 0]
    value = value * (1 + np.random.default_rng(0).normal(0, 0.003, value.shape))
    write_dng(path, np.round(BLACK_DN + np.clip(value, 0, 1) * (WHITE_DN - BLACK_DN)).astype(np.uint16))
    return rgb, inside


def test_reconstruct_reads_a_raw_highlights_clipped_channels_from_its_red(tmp_path, capsys):
    truth, inside = _white_disc_dng(tmp_path / "disc.dng")
    np.testing.assert_allclose(read_ldr_capture(tmp_path / "disc.dng").neutral_rgb, NEUTRAL, rtol=1e-3)
    assert main(["reconstruct", str(tmp_path / "disc.dng"), "--out", str(tmp_path / "out")]) == 0
    report = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    hdr = read_exr(tmp_path / "out" / "disc.exr").rgb()
    core = inside & (np.hypot(*(np.mgrid[:96, :96] - 47.5)) <= 12)  # beyond the demosaic's reach of the edge
    np.testing.assert_allclose(np.median(hdr[core], axis=0)[1:], truth[core][0, 1:], rtol=0.03)
    assert report["colour_filled_samples"] >= 2 * int(core.sum())
