"""The fit's move to the target's scale (`fitting._scale`), against a power law whose
answer is known: wavelength = c x length ** power."""

import numpy as np
import pytest

from fitting._scale import (
    CHI2_1_95,
    SNAP_TOLERANCE,
    moved_length,
    snap_threshold,
    snap_to_wavelength,
)

C, POWER = 8.0, 0.5


def wavelength_at(theta):
    return C * theta[1] ** POWER


def test_moved_length_lands_on_the_target_under_the_power_law():
    lengths = np.array([0.5, 1.0, 2.0])
    moved = moved_length(lengths, C * lengths**POWER, 10.0, POWER, 0.01, 100.0)
    np.testing.assert_allclose(C * moved**POWER, 10.0, rtol=1e-12)


def test_moved_length_keeps_unknown_wavelengths_and_clips_to_the_bounds():
    moved = moved_length(np.array([1.0, 1.0, 1.0]), np.array([np.nan, 0.0, 1.0]), 10.0, POWER, 0.5, 4.0)
    np.testing.assert_array_equal(moved, [1.0, 1.0, 4.0])  # 100x the length asked for: the upper bound


def test_snap_threshold_is_the_one_parameter_likelihood_ratio_interval():
    assert snap_threshold(4, 1.0) == pytest.approx(1.25 * CHI2_1_95)
    assert snap_threshold(4, 3.0) == pytest.approx(3.0 * 1.25 * CHI2_1_95)
    assert snap_threshold(4, 0.2) == snap_threshold(4, 1.0)  # never narrower than a perfect model's


def _snap(theta, loss_at, threshold=5.0, low=0.01, high=100.0, target=10.0):
    loss, lam = loss_at(theta)
    return snap_to_wavelength(theta, loss, lam, loss_at, target_wavelength=target, index=1, power=POWER,
                              low=low, high=high, threshold=threshold)


def test_a_flat_loss_moves_the_point_to_the_target_wavelength():
    out = _snap(np.array([3.0, 2.25]), lambda th: (7.0, wavelength_at(th)))  # 12 cells against 10
    assert out["moved"]
    assert out["wavelength"] == pytest.approx(10.0)
    assert out["theta"][0] == 3.0  # only the length parameter moves


def test_a_move_that_costs_more_than_the_threshold_is_not_kept():
    def loss_at(theta):  # the loss rises by 50 per unit of length away from 2.25
        return 7.0 + 50.0 * abs(theta[1] - 2.25), wavelength_at(theta)

    out = _snap(np.array([3.0, 2.25]), loss_at)
    assert not out["moved"] and out["theta"][1] == 2.25 and len(out["tried"]) == 1


def test_a_cheap_move_is_kept_even_when_the_loss_rises_a_little():
    out = _snap(np.array([3.0, 2.25]), lambda th: (7.0 + 0.5 * abs(th[1] - 2.25), wavelength_at(th)))
    assert out["moved"] and out["loss"] > 7.0 and out["loss"] <= 7.0 + 5.0


def test_a_point_within_the_tolerance_is_left_alone():
    length = ((1.0 + SNAP_TOLERANCE / 2) * 10.0 / C) ** (1 / POWER)
    calls = []
    out = _snap(np.array([3.0, length]), lambda th: (calls.append(1), (7.0, wavelength_at(th)))[1])
    assert not out["moved"] and out["tried"] == [] and len(calls) == 1  # only the start's evaluation


def test_a_point_at_its_bound_stops_there():
    out = _snap(np.array([3.0, 4.0]), lambda th: (7.0, wavelength_at(th)), high=4.0, target=20.0)
    assert not out["moved"] and out["tried"] == []


def test_a_second_move_corrects_a_power_law_that_holds_only_roughly():
    def loss_at(theta):  # the true exponent is 0.6, the family declares 0.5
        return 7.0, C * theta[1] ** 0.6

    first = moved_length(2.25, C * 2.25**0.6, 10.0, POWER, 0.01, 100.0)
    out = _snap(np.array([3.0, 2.25]), loss_at)
    assert len(out["tried"]) == 2
    assert abs(out["wavelength"] / 10.0 - 1) < abs(C * first**0.6 / 10.0 - 1)
