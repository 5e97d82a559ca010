"""Analytic cases for the flock metrics in analysis.metrics."""
from __future__ import annotations

import math

import numpy as np

from analysis.metrics import mean_speed, polarization


def test_aligned_flock_has_polarization_one():
    vel = np.tile([0.3, -2.0, 1.0], (50, 1)) * np.linspace(0.5, 3.0, 50)[:, None]
    assert math.isclose(float(polarization(vel)), 1.0, rel_tol=1e-12)


def test_opposite_headings_cancel():
    vel = np.array([[1.0, 0, 0], [-2.0, 0, 0]])
    assert float(polarization(vel)) == 0.0


def test_random_headings_match_the_isotropic_expectation():
    # E|mean of N unit vectors uniform on the sphere| ~ sqrt(8 / (3 pi N)) for large N
    rng = np.random.default_rng(12)
    n, trials = 100, 4000
    vel = rng.standard_normal((trials, n, 3))
    values = polarization(vel)
    expected = math.sqrt(8 / (3 * math.pi * n))
    standard_error = values.std() / math.sqrt(trials)
    assert abs(values.mean() - expected) < 5 * standard_error + 0.01 * expected


def test_stopped_boids_are_left_out_and_all_stopped_is_nan():
    vel = np.array([[0.0, 0, 0], [0, 3.0, 0], [0, 1.0, 0]])
    assert float(polarization(vel)) == 1.0
    assert math.isnan(float(polarization(np.zeros((4, 3)))))


def test_time_series_shape_and_mean_speed():
    vel = np.zeros((7, 5, 3))
    vel[..., 0] = 2.0
    assert polarization(vel).shape == (7,)
    assert np.allclose(mean_speed(vel), 2.0)
