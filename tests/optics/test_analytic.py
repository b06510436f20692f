"""Hand-designed PSFs: energy, centre, geometry."""

from __future__ import annotations

import numpy as np
import pytest

from hdrcam.optics.analytic import (WINDSHIELD_ROTATION_DEG, dirac, dual_peak, sample_windshield_angle_deg, star,
                                    two_point_star)


@pytest.mark.parametrize("size", [31, 32])
def test_all_analytic_psfs_have_unit_energy_and_peak_on_axis(size):
    for psf in (dirac(size), star(size), dual_peak(size), two_point_star(size, 5.0)):
        assert psf.shape == (3, size, size) and psf.dtype == np.float32
        np.testing.assert_allclose(psf.sum(axis=(1, 2)), 1.0, rtol=1e-6)
        assert np.unravel_index(np.argmax(psf[1]), psf[1].shape) == (size // 2, size // 2)


def test_star_puts_its_streak_energy_on_the_requested_number_of_rays():
    psf = star(65, points=8, centre_fraction=0.9)[0]
    assert psf[32, 32] == pytest.approx(0.9, rel=1e-6)
    rows, columns = np.mgrid[:65, :65] - 32
    angle = np.degrees(np.arctan2(-rows, columns)) % 360
    streak = psf.copy()
    streak[32, 32] = 0
    assert streak.sum() == pytest.approx(0.1, rel=1e-5)
    distance_to_ray = np.abs((angle + 22.5) % 45 - 22.5)  # degrees to the nearest of the 8 rays
    for ray in range(8):
        sector = np.abs((angle - 45 * ray + 180) % 360 - 180) < 22.5
        assert streak[sector].sum() == pytest.approx(0.1 / 8, rel=0.1)
    between_rays = (distance_to_ray > 8) & (np.hypot(rows, columns) > 8)
    assert streak[between_rays].sum() < 0.01 * 0.1


def test_dual_peak_places_the_secondary_peak_at_the_offset():
    psf = dual_peak(33, offset_px=(-3, 5), secondary_fraction=0.1)[2]
    assert psf[16, 16] == pytest.approx(0.9) and psf[13, 21] == pytest.approx(0.1)


@pytest.mark.parametrize("angle", [-8.0, -2.5, 4.0])
def test_two_point_star_streak_is_rotated_from_vertical_by_the_angle(angle):
    psf = two_point_star(101, angle, centre_fraction=0.0)[0]
    rows, columns = np.mgrid[:101, :101] - 50
    covariance = np.cov(np.stack([columns.ravel(), -rows.ravel()]), aweights=psf.ravel())
    eigenvalues, eigenvectors = np.linalg.eigh(covariance)
    x, y = eigenvectors[:, np.argmax(eigenvalues)]
    measured = np.degrees(np.arctan2(-x, y)) if y > 0 else np.degrees(np.arctan2(x, -y))
    assert measured == pytest.approx(angle, abs=0.3)


def test_windshield_angles_come_from_the_papers_range():
    rng = np.random.default_rng(0)
    angles = np.array([sample_windshield_angle_deg(rng) for _ in range(2000)])
    inside = np.zeros_like(angles, dtype=bool)
    for low, high in WINDSHIELD_ROTATION_DEG:
        inside |= (angles > low) & (angles < high)
    assert inside.all() and (angles < 0).mean() == pytest.approx(0.5, abs=0.05)
