"""Scratch: hdrcam CLI with procedural street lamps and headlights given a glow - GLOW=1: every lamp; GLOW=mix: each
with probability 0.5 (drawn first from the lamp's own generator); else unchanged."""
import os, sys
import numpy as np
import hdrcam.data.night_scene as ns

if os.environ.get("GLOW") in ("1", "mix"):
    MIX = os.environ["GLOW"] == "mix"
    plain_lamp, plain_head = ns._street_lamp, ns._headlights

    def _glow(scene, rng, x, y, radius, peak, colour):
        # a point source's glow (lens scatter, haze): exponential fall-off beyond the lamp, 0.3-8 % of its peak
        length = radius * rng.uniform(1.0, 6.0) + 1.0
        amplitude = peak * rng.uniform(0.003, 0.08)
        h, w = scene.shape[:2]
        reach = int(min(8 * length, 200))
        y0, y1, x0, x1 = max(0, y - reach), min(h, y + reach + 1), max(0, x - reach), min(w, x + reach + 1)
        if y0 >= y1 or x0 >= x1:
            return
        yy, xx = np.mgrid[y0:y1, x0:x1]
        r = np.hypot(yy - y, xx - x)
        scene[y0:y1, x0:x1] += (amplitude * np.exp(-r / length)).astype(np.float32)[..., None] * colour

    def _street_lamp(scene, rng):
        state = rng.bit_generator.state
        probe = np.random.default_rng()  # replay the lamp's draws to learn its centre, radius and peak
        probe.bit_generator.state = state
        x, y = ns._centre(scene, probe)
        radius = max(1, int(probe.uniform(0.004, 0.02) * scene.shape[1]))
        peak = probe.uniform(16.0, ns.HIGHLIGHT_PEAK)
        colour = ns._colour(probe)
        plain_lamp(scene, rng)
        g = np.random.default_rng([x, y, 7])
        if not MIX or g.random() < 0.5:
            _glow(scene, g, x, y, radius, peak, colour)

    def _headlights(scene, rng):
        state = rng.bit_generator.state
        probe = np.random.default_rng()
        probe.bit_generator.state = state
        x, y = ns._centre(scene, probe)
        separation = max(3, int(probe.uniform(0.01, 0.04) * scene.shape[1]))
        radius = max(1, separation // 6)
        peak = probe.uniform(64.0, ns.HIGHLIGHT_PEAK)
        plain_head(scene, rng)
        g = np.random.default_rng([x, y, 8])
        if MIX and g.random() >= 0.5:
            return
        for offset in (0, separation):
            _glow(scene, g, x + offset, y, radius, peak, np.array([1.0, 0.97, 0.92]))

    ns._street_lamp, ns._headlights = _street_lamp, _headlights
    import inspect
    src = inspect.getsource(ns.night_scene)
    assert "draw = (_street_lamp, _window, _led_grid, _headlights, _lettering)" in src

from hdrcam.cli import main
sys.exit(main(sys.argv[1:]))
