"""The design's placement by linear stability (`fitting._predicted`), against a NumPy oracle
of the Turing model's dispersion relation (leopard paper eqs. 3-4 linearised at (4, 4))."""

import numpy as np
import pytest

import morphojax as mj
from fitting._families import FAMILIES
from fitting._design import keep_better
from fitting._predicted import applies, place, predicted_wavelengths
from fitting._simulator import Simulator

NAMES = ["ratio", "scale", "lower_b"]


def turing_fastest_wavelength(ratio: float, scale: float) -> float:
    """The continuum's fastest-growing wavelength of da = 16 - ab + r s lap a,
    db = ab - b - 12 + s lap b at (a, b) = (4, 4), on a fine grid of wavenumbers."""
    jacobian = np.array([[-4.0, -4.0], [4.0, 3.0]])
    ks = np.geomspace(0.01, np.pi, 20000)
    rates = [np.linalg.eigvals(jacobian - k * k * np.diag([ratio * scale, scale])).real.max() for k in ks]
    return 2 * np.pi / ks[int(np.argmax(rates))]


@pytest.fixture(scope="module")
def turing_sim():
    fam = FAMILIES["turing"]
    return Simulator(fam.make((64, 64)), shape=(64, 64), steps=10, window=5)


def test_prediction_matches_the_numpy_dispersion(turing_sim):
    thetas = np.array([[20.0, 3.0, 1.0], [8.0, 0.5, 2.0], [12.0, 1.5, 0.0]])
    wavelength, valid = predicted_wavelengths(turing_sim, NAMES, thetas)
    assert valid.all()
    expected = [turing_fastest_wavelength(r, s) for r, s, _ in thetas]
    np.testing.assert_allclose(wavelength, expected, rtol=0.012)  # the grid's 1% spacing


def test_state_on_a_limit_or_stable_is_not_predicted(turing_sim):
    # lower_b 5 holds B above its steady state 4 (on the limit); ratio 2 is stable (no pattern)
    wavelength, valid = predicted_wavelengths(turing_sim, NAMES, np.array([[20.0, 1.0, 5.0], [2.0, 1.0, 0.0]]))
    assert not valid.any() and np.isnan(wavelength).all()


def test_place_moves_only_the_length_to_the_target(turing_sim):
    thetas = np.array([[20.0, 3.0, 1.0], [8.0, 0.5, 2.0], [20.0, 1.0, 5.0]])
    placed, ok = place(turing_sim, NAMES, thetas, 1, 10.0, 0.2, 8.0)
    assert ok.tolist() == [True, True, False]
    np.testing.assert_array_equal(placed[:, [0, 2]], thetas[:, [0, 2]])
    np.testing.assert_array_equal(placed[2], thetas[2])  # not placed: unchanged
    for r, s, _ in placed[:2]:
        assert turing_fastest_wavelength(r, s) == pytest.approx(10.0, rel=0.02)
    # the scale is a diffusion rate: the continuum's wavelength goes as its square root
    for before, after in zip(thetas[:2], placed[:2]):
        ratio = turing_fastest_wavelength(before[0], before[1]) / 10.0
        assert after[1] == pytest.approx(before[1] / ratio ** 2, rel=0.03)


def test_place_stops_at_a_bound(turing_sim):
    placed, ok = place(turing_sim, NAMES, np.array([[20.0, 3.0, 1.0]]), 1, 60.0, 0.2, 8.0)
    assert ok[0] and placed[0, 1] == 8.0


def test_which_families_are_placed():
    def sim(name):
        fam = FAMILIES[name]
        return Simulator(fam.make((32, 32)), shape=(32, 32), steps=10, window=5, anisotropic=fam.anisotropic)

    assert applies(sim("turing")) and applies(sim("bard"))
    # one species, an automaton, a polarised lattice: no dispersion relation to place by
    assert not any(applies(sim(n)) for n in ("reinforcement", "young", "anisotropic-turing"))


def test_only_turing_declares_placement_and_maps_have_no_dispersion():
    # declared from benchmarks/results/fit_placement.md: Bard's placed points missed
    assert [name for name, fam in FAMILIES.items() if fam.predicted] == ["turing"]
    maps = mj.Turing(ratio=np.full((8, 8), 12.0), scale=1.0)  # one steady state per cell: no single dispersion
    assert not applies(Simulator(maps, shape=(8, 8), steps=10, window=5))


def test_keep_better_replaces_only_the_rows_whose_move_scored_lower():
    thetas = np.arange(12.0).reshape(4, 3)
    vals, lams = np.array([5.0, 1.0, 3.0, 2.0]), np.array([10.0, 11.0, 12.0, 13.0])
    rows = np.array([0, 2, 3])  # row 1 was not moved
    moved = -np.ones((3, 3))
    new_thetas, new_vals, new_lams = keep_better(thetas, vals, lams, rows, moved, np.array([4.0, 3.0, 9.0]),
                                                 np.array([20.0, 21.0, 22.0]))
    np.testing.assert_array_equal(new_vals, [4.0, 1.0, 3.0, 2.0])  # a tie (row 2) keeps the point
    np.testing.assert_array_equal(new_lams, [20.0, 11.0, 12.0, 13.0])
    np.testing.assert_array_equal(new_thetas[0], [-1.0, -1.0, -1.0])
    np.testing.assert_array_equal(new_thetas[1:], thetas[1:])
    np.testing.assert_array_equal(vals, [5.0, 1.0, 3.0, 2.0])  # the inputs are left as they were
