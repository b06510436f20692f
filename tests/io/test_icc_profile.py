"""An embedded ICC profile's tone curves decide whether a TIFF's or PNG's values are linear."""

import numpy as np
import pytest

from hdrcam.io.icc_profile import CURVE_SAMPLES, _parametric, tone_curve_encoding
from tests.io.icc_profiles import SRGB_PARAMETERS, curv, para, profile, rgb_curves


@pytest.mark.parametrize("tag", [curv(), curv(gamma=1.0), para(0, 1.0), para(4, 1.0, 1.0, 0.0, 1.0, 0.0, 0.0, 0.0),
                                 curv(table=np.linspace(0.0, 1.0, 1024))])
def test_identity_tone_curves_are_linear(tag):
    assert tone_curve_encoding(rgb_curves(tag)) is None


@pytest.mark.parametrize("tag, said", [
    (curv(gamma=2.2), "gamma 2.2"),
    (curv(gamma=1.8), "gamma 1.8"),  # ProPhoto RGB
    (curv(gamma=257 / 256), "gamma 1.004"),  # the smallest step from 1 a u8Fixed8 gamma takes: not "gamma 1"
    (para(3, *SRGB_PARAMETERS), "gamma 2.4, piecewise"),
    (curv(table=np.linspace(0.0, 1.0, 1024) ** (1 / 2.2)), "a 1024-point tone curve"),
])
def test_encoding_tone_curves_are_named(tag, said):
    assert tone_curve_encoding(rgb_curves(tag)) == said


def test_one_encoded_channel_is_enough_to_refuse_linearity():
    assert tone_curve_encoding(rgb_curves(curv(), curv(), curv(gamma=2.2))) == "gamma 2.2"


def test_the_srgb_parametric_curve_is_evaluated_as_iec_61966_2_1():
    """Type 3: (a x + b)^g above d, c x below - the sRGB decoding function, checked against its closed form."""
    x = CURVE_SAMPLES
    expected = np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)
    np.testing.assert_allclose(_parametric(3, list(SRGB_PARAMETERS)), expected, atol=1e-9)


def test_a_profile_without_tone_curves_or_a_damaged_one_is_not_known_to_be_linear():
    assert tone_curve_encoding(profile({b"A2B0": b"mft2" + bytes(100)})) == "a LUT-based profile"
    # colour management applies a LUT before the curves (littleCMS: _cmsReadInputLUT): identity curves beside one
    # say nothing of the encoding
    assert tone_curve_encoding(profile({b"rTRC": curv(), b"gTRC": curv(), b"bTRC": curv(),
                                        b"A2B0": b"mft2" + bytes(100)})) == "a LUT-based profile"
    assert tone_curve_encoding(profile({b"kTRC": curv()})) == "no RGB tone curves: a grey, CMYK or LUT-based profile"
    linear = rgb_curves(curv())
    for damaged in (linear[:100], linear[:36] + b"xxxx" + linear[40:], rgb_curves(b"curv" + bytes(4) + b"\0\0\4\0"),
                    rgb_curves(b"sf32" + bytes(20))):
        assert tone_curve_encoding(damaged) == "damaged"


def test_littlecms_srgb_profile_reads_as_the_srgb_curve():
    """An ICC profile made by another writer (Pillow's littleCMS) than this file's builder."""
    image_cms = pytest.importorskip("PIL.ImageCms")
    srgb = image_cms.ImageCmsProfile(image_cms.createProfile("sRGB")).tobytes()
    assert tone_curve_encoding(srgb) == "gamma 2.4, piecewise"
