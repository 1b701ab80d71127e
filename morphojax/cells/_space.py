"""Where cells may sit (thesis 4.1 step 1, 4.2, 4.8.1 "define domain"): anywhere, a fixed
rectangle centred on the origin, or a packed square that grows with the number of cells.
Positions are clamped into the domain after every iteration (thesis 4.1, step 6)."""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
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


def as_domain(domain):
    """None, a `Box`, a `Packed`, a (width, height) pair or the string "packed"."""
    if domain is None or isinstance(domain, (Box, Packed)):
        return domain
    if isinstance(domain, str):
        if domain != "packed":
            raise ValueError(f"domain must be None, (width, height), 'packed', Box or Packed (got {domain!r})")
        return Packed()
    try:
        width, height = domain
    except (TypeError, ValueError):
        raise ValueError(f"domain must be None, (width, height), 'packed', Box or Packed (got {domain!r})") from None
    return Box(width, height)


def clamp_positions(domain, position: Array, count: Array) -> Array:
    """Positions clamped into the domain (unchanged when there is none)."""
    if domain is None:
        return position
    half = domain.half_extent(count)
    return jnp.clip(position, -half, half)
