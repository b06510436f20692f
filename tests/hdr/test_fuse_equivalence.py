"""The threaded, strip-wise fuse gives what the single-threaded merge gave (stored outputs of the code before
the speed work, on a small simulated bracket with hot pixels and clipped lamps), for any strip size."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import hdrcam.hdr.merge as merge
from hdrcam.hdr.fuse import fuse
from hdrcam.profiles import load_profile

DATA = Path(__file__).parent / "data"
BEFORE = np.load(DATA / "bracket-96x64-fused-before-threads.npz")


@pytest.mark.parametrize("strip_rows", [64, 16, 5])
def test_fuse_matches_the_single_threaded_merge(monkeypatch, strip_rows):
    monkeypatch.setattr(merge, "STRIP_ROWS", strip_rows)  # 1, 4 and 13 strips (odd strips start on a G/B row)
    image = fuse([DATA / "bracket-96x64"], load_profile("simulated").camera, camera_rgb=False, with_variance=True)
    for name, value in (("rate", image.merge.rate), ("variance", image.merge.variance), ("rgb", image.rgb),
                        ("exposures_s", image.merge.exposures_s)):
        np.testing.assert_allclose(value, BEFORE[name], rtol=1e-6, atol=0, err_msg=name)
    for name, value in (("clipped_everywhere", image.merge.clipped_everywhere),
                        ("usable_frames", image.merge.usable_frames), ("clipped", image.clipped)):
        np.testing.assert_array_equal(value, BEFORE[name], err_msg=name)
    assert BEFORE["clipped_everywhere"].any() and not BEFORE["clipped_everywhere"].all()
