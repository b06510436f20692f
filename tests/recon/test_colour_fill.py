"""The cross-channel fill (hdrcam.recon.colour_fill): a channel that clipped where another did not, read from the
unclipped channels and the highlight's hue, against scenes whose answer is known."""

import numpy as np
import pytest

from hdrcam.api import reconstruct
from hdrcam.colorimetry import camera_from_srgb
from hdrcam.errors import InputError
from hdrcam.recon.colour_fill import HUE_SHRINK, fill_from_unclipped_channels

CAMERA_NEUTRAL = tuple(camera_from_srgb() @ np.ones(3))  # a grey surface in the simulated A7's camera RGB


def _disc_scene(size_px=96, radius_px=14, disc_rgb=(2.0, 2.0, 2.0), ground_rgb=(0.5, 0.5, 0.5)) -> np.ndarray:
    rows, cols = np.mgrid[:size_px, :size_px]
    inside = (rows - size_px / 2) ** 2 + (cols - size_px / 2) ** 2 <= radius_px ** 2
    return np.where(inside[..., None], np.float32(disc_rgb), np.float32(ground_rgb)).astype(np.float32)


def test_a_white_highlight_clipped_in_green_and_blue_of_camera_rgb_is_read_from_its_red():
    """In camera RGB a white surface records (0.36, 1, 0.81) of green: a white disc at 2 x white clips green and
    blue while red reads 0.72; with a grey ground the rim's hue is the neutral's, so green and blue come back."""
    truth = _disc_scene() @ camera_from_srgb().T.astype(np.float32)
    frame = np.clip(truth, 0.0, 1.0)
    clipped = frame >= 1.0
    assert clipped[..., 1].any() and not clipped[..., 0].any()
    filled, raised = fill_from_unclipped_channels(frame, frame, CAMERA_NEUTRAL)
    assert raised == int(clipped.sum())
    np.testing.assert_allclose(filled[clipped], truth[clipped], rtol=1e-4)
    np.testing.assert_array_equal(filled[~clipped], frame[~clipped])
    # told the frame is white-balanced, the fill takes the grey ground's camera-RGB hue as the rim's: the same
    # answer, since the rim here is grey too; only the shrink toward the wrong neutral moves it
    wrong, _ = fill_from_unclipped_channels(frame, frame)
    green_over_red = CAMERA_NEUTRAL[1] / CAMERA_NEUTRAL[0]
    expected = frame[..., 0] * green_over_red ** HUE_SHRINK
    np.testing.assert_allclose(wrong[..., 1][clipped[..., 1]], np.maximum(expected, 1.0)[clipped[..., 1]], rtol=1e-4)


def test_a_coloured_rim_is_shrunk_toward_the_neutral():
    """A glint on brass: the rim reads red / blue = 8 (0.8 against 0.1), the glint's blue is unclipped at 0.5.
    The rim's hue taken whole would say red = 4; shrunk by HUE_SHRINK toward the neutral's 1, 0.5 x 8^0.75."""
    frame = _disc_scene(disc_rgb=(1.0, 1.0, 0.5), ground_rgb=(0.8, 0.8, 0.1))
    filled, _ = fill_from_unclipped_channels(frame, frame)
    centre = frame.shape[0] // 2
    np.testing.assert_allclose(filled[centre, centre, :2], 0.5 * 8.0 ** HUE_SHRINK, rtol=1e-4)
    assert filled[centre, centre, 2] == 0.5


@pytest.mark.parametrize("name, frame", [
    ("nothing clipped", _disc_scene(disc_rgb=(0.9, 0.8, 0.7))),
    ("every channel clipped", _disc_scene(disc_rgb=(3.0, 3.0, 3.0)).clip(0.0, 1.0)),
    ("all white", np.ones((32, 48, 3), np.float32)),
    ("all black", np.zeros((32, 48, 3), np.float32)),
])
def test_frames_without_partly_clipped_pixels_are_left_as_they_are(name, frame):
    frame = np.clip(frame, 0.0, 1.0)
    filled, raised = fill_from_unclipped_channels(frame, frame)
    assert raised == 0 and np.array_equal(filled, frame), name


def test_the_fill_never_lowers_the_judged_value_nor_goes_below_white():
    """A judged estimate above the cross-channel one is kept; a barely clipped green beside a red and blue whose
    hue does not lift it stays at the clip level, not below it."""
    frame = _disc_scene(disc_rgb=(0.6, 1.02, 0.6), ground_rgb=(0.5, 0.5, 0.5)).clip(0.0, 1.0)
    judged = frame.copy()
    centre = frame.shape[0] // 2
    judged[centre, centre, 1] = 5.0
    filled, _ = fill_from_unclipped_channels(frame, judged)
    assert filled[centre, centre, 1] == 5.0
    elsewhere = frame[..., 1] >= 1.0
    elsewhere[centre, centre] = False
    assert elsewhere.any() and (filled[..., 1][elsewhere] == 1.0).all()


def test_the_fill_is_bounded_at_extreme_inputs():
    """A reference channel at the noise floor and a rim at full scale: finite, at least 1, at most what the
    rim's hue allows."""
    frame = _disc_scene(disc_rgb=(1.0, 1e-7, 1e-7), ground_rgb=(0.99, 0.05, 0.05))
    filled, _ = fill_from_unclipped_channels(frame, frame)
    assert np.isfinite(filled).all() and filled.min() >= 0.0
    assert filled[..., 0].max() <= 0.99 / 0.05 * 1.0001


@pytest.mark.parametrize("neutral", [(1.0, 0.0, 1.0), (1.0, float("nan"), 1.0), (1.0, 1.0), (-1.0, 1.0, 1.0), "grey"])
def test_a_neutral_that_is_not_three_positive_numbers_is_refused_before_any_work(neutral):
    frame = np.zeros((8, 8, 3), np.float32)
    with pytest.raises(InputError, match="neutral_rgb"):
        fill_from_unclipped_channels(frame, frame, neutral)
    with pytest.raises(InputError, match="neutral_rgb"):
        reconstruct(frame, model=object(), neutral_rgb=neutral)  # refused before the model is used
