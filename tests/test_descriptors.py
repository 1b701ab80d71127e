"""Pattern descriptors on synthetic images whose answers are known by construction."""

import jax.numpy as jnp
import numpy as np
import pytest

from morphojax._descriptors import describe, dominant_wavelength, regions, relative_change


def discs(shape, centres, radius, inside=1.0, outside=0.0):
    r, c = np.indices(shape)
    x = np.full(shape, outside, float)
    for cy, cx in centres:
        # periodic distance, so a disc over the border wraps to the other side
        dy = np.minimum(np.abs(r - cy), shape[0] - np.abs(r - cy))
        dx = np.minimum(np.abs(c - cx), shape[1] - np.abs(c - cx))
        x[dy**2 + dx**2 <= radius**2] = inside
    return x


GRID = [(8 + 16 * i, 8 + 16 * j) for i in range(4) for j in range(4)]  # 16 separated discs on 64x64


def test_separated_discs_are_spots_with_the_right_count_and_area():
    x = discs((64, 64), GRID, 4)
    d = describe(x)
    assert d.pattern == "spots"
    assert d.spots == 16
    one = discs((64, 64), GRID[:1], 4)
    assert d.spot_area == pytest.approx(one.sum())  # every disc has the same pixel area
    assert d.dark_fraction == pytest.approx(1 - x.mean())
    assert d.holes == 1  # one connected background


def test_dark_discs_on_bright_are_inverted_spots():
    d = describe(discs((64, 64), GRID, 4, inside=0.0, outside=1.0))
    assert d.pattern == "inverted spots"
    assert d.holes == 16


def test_disc_across_the_corner_counts_once_with_wrap_and_four_times_without():
    x = discs((48, 48), [(0, 0), (24, 24), (24, 0)], 5)
    assert describe(x, wrap=True).spots == 3
    lab, areas = regions(x > 0.5, wrap=False)
    assert len(areas) == 3 + 3 + 1  # corner disc in 4 pieces, edge disc in 2, centre disc whole
    assert describe(x, wrap=True).pattern == "spots"


def test_stripes_are_stripes_labyrinth():
    c = np.arange(64)
    x = np.broadcast_to(np.sin(2 * np.pi * c / 8), (64, 64))
    assert describe(x).pattern == "stripes-labyrinth"


def test_constant_is_uniform_and_nan_is_unstable():
    assert describe(np.full((32, 32), 4.0)).pattern == "uniform"
    x = np.full((32, 32), 4.0)
    x[3, 4] = np.nan
    d = describe(x)
    assert d.pattern == "unstable" and not d.finite


@pytest.mark.parametrize("direction", ["x", "y", "diagonal"])
def test_dominant_wavelength_of_a_pure_sinusoid(direction):
    r, c = np.indices((64, 64))
    phase = {"x": c / 8, "y": r / 8, "diagonal": (r + c) / 16}[direction]  # diagonal: period 16/sqrt(2)
    expected = 8.0 if direction != "diagonal" else 16 / np.sqrt(2)
    tol = 0.05 if direction != "diagonal" else 0.1  # off-axis frequencies fall between radial bins
    assert dominant_wavelength(np.sin(2 * np.pi * phase)) == pytest.approx(expected, rel=tol)


def test_relative_change_numpy_and_jax_agree_and_settled_follows_it():
    rng = np.random.default_rng(0)
    last = rng.normal(5.0, 1.0, (2, 32, 32))
    prev = last + 0.02 * rng.normal(size=last.shape)
    want = max(np.sqrt(((last[k] - prev[k]) ** 2).mean()) / last[k].std() for k in range(2))
    assert relative_change(prev, last) == pytest.approx(want, rel=1e-9)
    assert float(relative_change(jnp.asarray(prev, jnp.float32), jnp.asarray(last, jnp.float32), xp=jnp)) == \
        pytest.approx(want, rel=1e-4)
    assert relative_change(last, last) == 0.0
    d = describe(last[0], previous=prev[0])
    assert d.settled is True and d.change == pytest.approx(relative_change(prev[0], last[0]))
    moved = describe(last[0], previous=np.roll(last[0], 3, axis=1))
    assert moved.settled is False and moved.change > 1.0
    assert describe(last[0]).settled is None  # not measured without `previous`
    # a field relaxing to a constant: the floor keeps the ratio finite and small
    flat = np.full((16, 16), 4.0)
    assert relative_change(flat + 1e-7, flat) < 1e-3
