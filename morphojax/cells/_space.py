"""Where cells may sit (thesis 4.1 step 1, 4.2, 4.8.1 "define domain", 4.8.3 "wrap"):
anywhere, a fixed rectangle centred on the origin, a packed square that grows with the
number of cells, or a torus (a periodic rectangle centred on the origin). Positions are
clamped into a rectangle after every iteration (thesis 4.1, step 6), and wrapped into a
torus, whose opposite edges touch: there the offset between two cells is the shortest of
its periodic images (the minimum-image convention, `minimum_image`)."""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jax import Array

from .._checks import as_float_array, check_finite, check_range

PACKING_AREA = 3.2  # thesis 4.2: area per cell of a packed domain (pi < a < 4; 2 sqrt(3) is hexagonal)


class Box(eqx.Module):
    """A fixed `width` x `height` rectangle centred on the origin ("define domain W H")."""

    width: Array
    height: Array

    def __init__(self, width, height):
        self.width, self.height = as_float_array(width, "Box.width"), as_float_array(height, "Box.height")
        for name in ("width", "height"):
            check_finite(getattr(self, name), f"Box.{name}")
            check_range(getattr(self, name), f"Box.{name}", low=0.0, low_open=True)

    def half_extent(self, count: Array) -> Array:
        return jnp.stack([self.width, self.height]) / 2


class Packed(eqx.Module):
    """A square centred on the origin whose area is `area` per live cell ("define domain
    packed [area a]"): it grows as cells divide, pressing them into a dense tissue so that
    growth is uniform (thesis 4.2; a = 3.2 by default)."""

    area: Array

    def __init__(self, area=PACKING_AREA):
        self.area = as_float_array(area, "Packed.area")
        check_finite(self.area, "Packed.area")
        check_range(self.area, "Packed.area (per cell, in cell radii squared)", low=0.0, low_open=True)

    def half_extent(self, count: Array) -> Array:
        side = jnp.sqrt(self.area * count.astype(self.area.dtype))
        return jnp.stack([side, side]) / 2


class Torus(eqx.Module):
    """A `width` x `height` rectangle centred on the origin whose opposite edges touch
    (`create sqr_grid COLS ROWS wrap`: COLS x ROWS cells at the grid's spacing, so the
    grid tiles the plane). Its sides are static: they size the neighbour search's buckets.
    The minimum-image convention needs each side at least twice the neighbour search's
    radius (`simulate_cells` checks it), so that a cell meets another through one image."""

    width: float = eqx.field(static=True)
    height: float = eqx.field(static=True)

    def __init__(self, width, height):
        self.width, self.height = check_period((width, height), "Torus")

    @property
    def period(self) -> tuple[float, float]:
        return self.width, self.height

    def half_extent(self, count: Array) -> Array:
        return jnp.asarray(self.period) / 2


def check_period(period, name: str = "period") -> tuple[float, float] | None:
    """A torus's (width, height) as floats, each in (0, +inf); None stays None."""
    if period is None:
        return None
    try:
        width, height = period
        sides = {"width": float(width), "height": float(height)}
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be None or (width, height), each in (0, +inf) (got {period!r})") from None
    for side, value in sides.items():
        if isinstance((width, height)[side == "height"], bool) or not 0 < value < np.inf:
            raise ValueError(f"{name} {side} must lie in (0, +inf) (got {value:g})")
    return sides["width"], sides["height"]


def minimum_image(offset: Array, length: float) -> Array:
    """The shortest periodic image of offsets along an axis of period `length`: offsets
    within half a period are returned exactly as they are."""
    return offset - length * jnp.round(offset / length)


def wrap_positions(position: Array, period) -> Array:
    """Positions (n, 2) wrapped into the torus [-w/2, w/2) x [-h/2, h/2); those already
    inside are returned exactly as they are."""
    size = jnp.asarray(period, position.dtype)
    return position - size * jnp.floor((position + size / 2) / size)


def as_domain(domain):
    """None, a `Box`, a `Packed`, a `Torus`, a (width, height) pair or the string "packed"."""
    if domain is None or isinstance(domain, (Box, Packed, Torus)):
        return domain
    if isinstance(domain, str):
        if domain != "packed":
            raise ValueError(f"domain must be None, (width, height), 'packed', Box, Packed or Torus (got {domain!r})")
        return Packed()
    try:
        width, height = domain
    except (TypeError, ValueError):
        raise ValueError(f"domain must be None, (width, height), 'packed', Box, Packed or Torus (got {domain!r})") from None
    return Box(width, height)


def clamp_positions(domain, position: Array, count: Array) -> Array:
    """Positions clamped into the domain, or wrapped into a torus (unchanged when there is none)."""
    if domain is None:
        return position
    if isinstance(domain, Torus):
        return wrap_positions(position, domain.period)
    half = domain.half_extent(count)
    return jnp.clip(position, -half, half)
