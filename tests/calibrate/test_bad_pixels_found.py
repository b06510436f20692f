"""Bad pixels found in a simulated camera's frames against the hot pixels the simulator drew (its ground truth)."""

from __future__ import annotations

import numpy as np

import hdrcam
from hdrcam.capture.simulated import SensorDefects

WIDTH, HEIGHT, HOT_FRACTION, SEED = 192, 128, 1.5e-3, 5


def test_the_hot_pixels_of_simulated_darks_are_found_and_nothing_else(tmp_path):
    """Darks of 1/30, 1/8 and 1/2 s: each hot pixel's dark charge (0.2-4 full wells per second) is at least
    ~170 e- in the shortest, far above the 4 e- of read noise, so all are found; flat fields at half the full
    well, whose shot noise (~90 e-) hides the hot pixels' charge in some frame, find none - and nothing false."""
    options = dict(camera="sim", profile="simulated", size_px=(WIDTH, HEIGHT), shortest_s=1 / 30, stops=3,
                   ev_step=2.0, seed=SEED, hot_pixel_fraction=HOT_FRACTION)
    hdrcam.capture_bracket(tmp_path / "flats", scene="flat:0.5", darks=True, **options)
    truth = SensorDefects.draw(HEIGHT, WIDTH, HOT_FRACTION, SEED)
    hot = np.zeros((HEIGHT, WIDTH), bool)
    hot[truth.hot_pixel_rows, truth.hot_pixel_columns] = True
    assert hot.sum() == 37
    assert np.array_equal(hdrcam.find_bad_pixels(sorted((tmp_path / "flats" / "darks").glob("*.dng"))), hot)
    assert not hdrcam.find_bad_pixels(sorted((tmp_path / "flats").glob("*.dng"))).any()
