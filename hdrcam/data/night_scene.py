"""Procedural night scenes: a dim textured background plus emissive sources up to 2^8 (relative radiance).

Relative radiance 1.0 is the level that just fills the sensor at the reference exposure; the paper's
highlights reach 2^8 (Sec. 4.3). Sources: street lamps (round, with a brighter core), lit windows,
LED grids, headlight pairs and lit lettering (shop signs). Everything is drawn from one seed.
"""

from __future__ import annotations

import cv2
import numpy as np

HIGHLIGHT_PEAK = 256.0  # 2^8, the paper's highest radiance


def night_scene(height_px: int, width_px: int, seed: int = 0, sources: int = 12) -> np.ndarray:
    """An H x W x 3 float32 night scene with ``sources`` emitters on a background of 0.005-0.3."""
    rng = np.random.default_rng(seed)
    scene = _background(height_px, width_px, rng)
    draw = (_street_lamp, _window, _led_grid, _headlights, _lettering)
    for _ in range(sources):
        draw[rng.integers(len(draw))](scene, rng)
    return np.clip(scene, 0.0, None).astype(np.float32)


def _background(height_px: int, width_px: int, rng: np.random.Generator) -> np.ndarray:
    """Multi-scale texture (noise octaves, amplitude growing with scale), tinted, between about 0.005 and 0.3."""
    texture = np.zeros((height_px, width_px), np.float32)
    for octave in range(1, 6):
        scale = 2 ** octave
        small = rng.random((max(2, height_px // scale), max(2, width_px // scale))).astype(np.float32)
        texture += cv2.resize(small, (width_px, height_px), interpolation=cv2.INTER_CUBIC) * scale  # ~1/f
    texture = (texture - texture.min()) / max(float(np.ptp(texture)), 1e-6)
    level = 0.005 * (60.0 ** texture)  # log-uniform-ish from 0.005 to 0.3
    tint = rng.uniform(0.7, 1.0, 3).astype(np.float32)
    return level[..., None] * tint


def _colour(rng: np.random.Generator) -> np.ndarray:
    warm = np.array([1.0, 0.75, 0.45]), np.array([1.0, 0.95, 0.9]), np.array([0.8, 0.9, 1.0])
    return warm[rng.integers(3)] * rng.uniform(0.8, 1.0)


def _centre(scene: np.ndarray, rng: np.random.Generator) -> tuple[int, int]:
    height, width = scene.shape[:2]
    return int(rng.integers(0, width)), int(rng.integers(0, height))


def _street_lamp(scene: np.ndarray, rng: np.random.Generator) -> None:
    x, y = _centre(scene, rng)
    radius = max(1, int(rng.uniform(0.004, 0.02) * scene.shape[1]))
    peak = rng.uniform(16.0, HIGHLIGHT_PEAK)
    mask = np.zeros(scene.shape[:2], np.float32)
    cv2.circle(mask, (x, y), radius, 1.0, -1, lineType=cv2.LINE_AA)
    core = np.zeros_like(mask)
    cv2.circle(core, (x, y), max(1, radius // 3), 1.0, -1, lineType=cv2.LINE_AA)
    emission = (0.4 * mask + 0.6 * core) * peak
    scene += emission[..., None] * _colour(rng)


def _window(scene: np.ndarray, rng: np.random.Generator) -> None:
    x, y = _centre(scene, rng)
    width = max(2, int(rng.uniform(0.01, 0.05) * scene.shape[1]))
    height = max(2, int(width * rng.uniform(0.8, 1.6)))
    mask = np.zeros(scene.shape[:2], np.float32)
    cv2.rectangle(mask, (x, y), (x + width, y + height), 1.0, -1)
    cv2.line(mask, (x + width // 2, y), (x + width // 2, y + height), 0.3, max(1, width // 10))  # mullion
    scene += (mask * rng.uniform(2.0, 12.0))[..., None] * _colour(rng)


def _led_grid(scene: np.ndarray, rng: np.random.Generator) -> None:
    x, y = _centre(scene, rng)
    spacing = max(2, int(rng.uniform(0.004, 0.01) * scene.shape[1]))
    rows, columns = rng.integers(2, 6), rng.integers(3, 10)
    peak = rng.uniform(32.0, HIGHLIGHT_PEAK)
    colour = np.array([[1.0, 0.1, 0.1], [0.1, 1.0, 0.2], [0.3, 0.5, 1.0]])[rng.integers(3)]
    height, width = scene.shape[:2]
    for row in range(rows):
        for column in range(columns):
            yy, xx = y + row * spacing, x + column * spacing
            if 0 <= yy < height and 0 <= xx < width:
                scene[yy, xx] += peak * colour


def _headlights(scene: np.ndarray, rng: np.random.Generator) -> None:
    x, y = _centre(scene, rng)
    separation = max(3, int(rng.uniform(0.01, 0.04) * scene.shape[1]))
    radius = max(1, separation // 6)
    mask = np.zeros(scene.shape[:2], np.float32)
    for offset in (0, separation):
        cv2.circle(mask, (x + offset, y), radius, 1.0, -1, lineType=cv2.LINE_AA)
    scene += (mask * rng.uniform(64.0, HIGHLIGHT_PEAK))[..., None] * np.array([1.0, 0.97, 0.92])


_SIGN_WORDS = ("OPEN", "HOTEL", "BAR", "24H", "PHARMACY", "EXIT", "CAFE", "TAXI", "KEBAB", "PARKING")


def _lettering(scene: np.ndarray, rng: np.random.Generator) -> None:
    """A lit sign: a word in anti-aliased stroked letters at 4-64."""
    x, y = _centre(scene, rng)
    word = _SIGN_WORDS[rng.integers(len(_SIGN_WORDS))]
    scale = rng.uniform(0.0015, 0.004) * scene.shape[1]
    thickness = max(1, int(round(scale * rng.uniform(0.8, 1.6))))
    mask = np.zeros(scene.shape[:2], np.uint8)  # OpenCV draws text on 8-bit images only
    cv2.putText(mask, word, (x, y), cv2.FONT_HERSHEY_SIMPLEX, scale / 10.0, 255, thickness, cv2.LINE_AA)
    scene += (mask.astype(np.float32) * (rng.uniform(4.0, 64.0) / 255.0))[..., None] * _colour(rng)
