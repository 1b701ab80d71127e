"""Rules evaluated per cell on the current state (thesis 4.8.5, Table 4.1): every rule's
conditions give a mask, its action adds to the iteration's effects (changes, reactions,
division requests, mapped values, polarities), all read from the current state so the
order of cells never matters (thesis 4.1, step 2). Polarization is eq. 4.10."""

from __future__ import annotations

from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from ._contacts import Contacts
from ._rules import Always, Chance, Change, Compare, Divide, Map, Polarize, React, Rule, Var, Within
from ._state import Cells


class _Effects(NamedTuple):
    """What the rules ask for this iteration, accumulated over the rules."""

    conc: Array
    rates: Array
    divide: Array
    direction: Directions
    polarise: Array
    polarity: Array
    maps: dict


def _value(v, cells: Cells, near_count: Array, iteration: Array, maps: dict):
    if not isinstance(v, Var):
        return v
    if v.kind == "conc":
        return cells.concentration[cells.index(v.name)]
    if v.kind == "diff":
        return cells.diffusion[cells.index(v.name)]
    if v.kind == "AGE":
        return (iteration - cells.birth).astype(cells.position.dtype)
    if v.kind == "BIRTH":
        return cells.birth.astype(cells.position.dtype)
    if v.kind == "NEIGHBORS":
        return near_count.astype(cells.position.dtype)
    return maps[v.name]


_COMPARE = {
    "==": jnp.equal, "!=": jnp.not_equal, "<": jnp.less,
    "<=": jnp.less_equal, ">": jnp.greater, ">=": jnp.greater_equal,
}


def _holds(condition, value, key: Array, capacity: int) -> Array:
    if isinstance(condition, Always):
        return jnp.ones(capacity, bool)
    if isinstance(condition, Compare):
        return jnp.broadcast_to(_COMPARE[condition.op](value(condition.left), value(condition.right)), (capacity,))
    if isinstance(condition, Within):
        x = value(condition.value)
        return jnp.broadcast_to((x >= value(condition.low)) & (x <= value(condition.high)), (capacity,))
    assert isinstance(condition, Chance)
    return uniform(key, capacity) < value(condition.probability)


class Directions(eqx.Module):
    """The division angles the rules asked for (added to the polarity), drawn only for the
    cells that divide (a few an iteration, against one draw per cell of capacity).

    Attributes:
        rule: (capacity,) int32, per cell the `Divide` (its place in `draws`) that set its
            angle, the first that fired; -1 where none did (angle 0).
        draws: per `Divide`, (direction, spread, key): the angle of cell i is direction +
            spread x the i-th of `uniform(key, capacity, -1, 1)`, as drawn for every cell.
    """

    rule: Array
    draws: tuple
    dtype: object = eqx.field(static=True)

    def at(self, index: Array) -> Array:
        """The angles of the cells `index` (clipped into the capacity)."""
        capacity = self.rule.shape[0]
        index = jnp.clip(index, 0, capacity - 1)
        which = jnp.take(self.rule, index)
        angle = jnp.zeros(index.shape, self.dtype)
        for k, (direction, spread, key) in enumerate(self.draws):
            drawn = direction + spread * uniform_at(key, index, capacity, -1.0, 1.0)
            angle = jnp.where(which == k, drawn, angle)
        return angle

    def full(self) -> Array:
        """Every cell's angle, (capacity,)."""
        return self.at(jnp.arange(self.rule.shape[0]))


def _gradient(cells: Cells, touch: Contacts, name: str) -> Array:
    """Eq. 4.10: sum_j (R_j - R_i) d_j / |d_j|, per cell (C, 2)."""
    r = cells[name]
    rise = jnp.where(touch.near, jnp.take(r, touch.index, mode="clip") - r[:, None], 0.0)
    return jnp.stack([jnp.sum(rise * touch.ux, axis=1), jnp.sum(rise * touch.uy, axis=1)], axis=1)


def apply_rules(rules: tuple[Rule, ...], cells: Cells, touch: Contacts, iteration: Array, dt: Array,
                key: Array) -> _Effects:
    """The accumulated effects of every rule on the current state (thesis 4.8.5)."""
    capacity = cells.capacity
    near_count = touch.count
    fx = _Effects(
        conc=jnp.zeros_like(cells.concentration), rates=jnp.zeros_like(cells.diffusion),
        divide=jnp.zeros(capacity, bool), direction=Directions(jnp.full(capacity, -1, jnp.int32), (),
                                                               cells.polarity.dtype),
        polarise=jnp.zeros(capacity, bool), polarity=cells.polarity, maps={},
    )
    alive = cells.alive
    for k, rule in enumerate(rules):
        rule_key = jax.random.fold_in(key, k)
        maps = dict(fx.maps)

        def value(v, maps=maps):
            return _value(v, cells, near_count, iteration, maps)

        mask = alive & rule.active(iteration)
        for c, condition in enumerate(rule.when):
            condition_key = jax.random.fold_in(rule_key, c)
            if isinstance(condition, Chance):  # no draws where no cell can fire (outside the rule's window)
                mask &= jax.lax.cond(jnp.any(mask), lambda c=condition, k=condition_key: _holds(c, value, k, capacity),
                                     lambda: jnp.zeros(capacity, bool))
            else:
                mask &= _holds(condition, value, condition_key, capacity)
        action_key = jax.random.fold_in(rule_key, len(rule.when))
        fx = _act(rule.action, fx, mask, value, cells, touch, dt, action_key, maps)
    return fx


def _uniform(key, shape, amplitude):
    return amplitude * uniform(key, shape[0], -1.0, 1.0)


try:  # the 20 rounds of Threefry as plain array operations (jax's own, unrolled)
    from jax._src.random.threefry2x32 import _threefry2x32_lowering as _threefry_rounds
except ImportError:  # another jax: its own uniform
    _threefry_rounds = None


def uniform(key: Array, n: int, low: float = 0.0, high: float = 1.0) -> Array:
    """`jax.random.uniform(key, (n,), float32, low, high)`, the same bits, cheaper on a CPU.

    XLA's CPU lowering of Threefry rolls its 20 rounds into a loop of 5 trips, each a few
    small kernels; for the thousands of draws a cell rule makes every iteration that loop
    costs several times the arithmetic. Here the rounds are unrolled into one fusion (jax's
    GPU lowering, the same function). Keys other than Threefry's, the non-partitionable
    bit scheme or a jax without that function take `jax.random.uniform` itself;
    `tests/test_cells.py::test_uniform_draws_the_bits_of_jax_random` holds them equal."""
    if (_threefry_rounds is None or not jax.config.jax_threefry_partitionable
            or str(jax.random.key_impl(key)) != "threefry2x32"):
        return jax.random.uniform(key, (n,), minval=low, maxval=high)
    return _uniform_of(key, jnp.arange(n, dtype=jnp.uint32), low, high)


def uniform_at(key: Array, index: Array, n: int, low: float = 0.0, high: float = 1.0) -> Array:
    """`uniform(key, n, low, high)[index]` (index within [0, n)), drawing only those entries:
    with Threefry's partitionable bit scheme, entry i's bits depend on i alone."""
    if (_threefry_rounds is None or not jax.config.jax_threefry_partitionable
            or str(jax.random.key_impl(key)) != "threefry2x32"):
        return jnp.take(jax.random.uniform(key, (n,), minval=low, maxval=high), index, mode="clip")
    return _uniform_of(key, index.astype(jnp.uint32), low, high)


def _uniform_of(key: Array, count: Array, low: float, high: float) -> Array:
    """The uniform draws of the entries `count` (uint32) of Threefry's partitionable scheme."""
    k = jax.random.key_data(key)
    # count: the low word of the iota; the high word is 0 (n < 2**32)
    bits1, bits2 = _threefry_rounds(k[0], k[1], jnp.zeros_like(count), count, use_rolled_loops=False)
    bits = (bits1 ^ bits2) >> np.uint32(32 - 23) | np.uint32(0x3F800000)  # a float in [1, 2)
    floats = jax.lax.bitcast_convert_type(bits, jnp.float32) - jnp.float32(1.0)
    low32, high32 = jnp.float32(low), jnp.float32(high)
    return jnp.maximum(low32, floats * (high32 - low32) + low32)


def _act(action, fx: _Effects, mask: Array, value, cells: Cells, touch: Contacts, dt, key, maps) -> _Effects:
    capacity = cells.capacity
    if isinstance(action, Change):
        amount = jnp.broadcast_to(value(action.amount), (capacity,)) + _uniform(key, (capacity,), action.spread)
        row = cells.index(action.target.name)
        delta = jnp.where(mask, amount, 0.0)
        if action.target.kind == "conc":
            return fx._replace(conc=fx.conc.at[row].add(delta))
        return fx._replace(rates=fx.rates.at[row].add(delta))
    if isinstance(action, React):
        rows = jnp.asarray([cells.index(name) for name in action.species])
        # cells the rule skips (and unused capacity, all zeros) react on a harmless 1, so a
        # reaction singular at 0 (Gierer-Meinhardt) leaves no NaN in the gradient
        x = jnp.where(mask, cells.concentration[rows], 1.0)
        rate = action.model.reaction(x) * (dt * value(action.scale))
        return fx._replace(conc=fx.conc.at[rows].add(jnp.where(mask, rate, 0.0)))
    if isinstance(action, Divide):
        first = mask & ~fx.divide  # the first divide rule that fires sets the direction
        old = fx.direction
        direction = Directions(jnp.where(first, len(old.draws), old.rule), old.draws + ((action.direction,
                                                                                         action.spread, key),),
                               old.dtype)
        return fx._replace(divide=fx.divide | mask, direction=direction)
    if isinstance(action, Map):
        low, high, a, b = (value(v) for v in (action.low, action.high, action.out_low, action.out_high))
        span = jnp.where(high != low, high - low, 1.0)
        out = jnp.clip(a + (value(action.source) - low) * (b - a) / span, jnp.minimum(a, b), jnp.maximum(a, b))
        previous = maps.get(action.name, jnp.zeros(capacity, cells.position.dtype))
        new_maps = dict(maps)
        new_maps[action.name] = jnp.where(mask, jnp.broadcast_to(out, (capacity,)), previous)
        return fx._replace(maps=new_maps)
    assert isinstance(action, Polarize)
    p = _gradient(cells, touch, action.reagent)
    steered = mask & (jnp.sum(p * p, axis=1) > 0)
    angle = jnp.arctan2(p[:, 1], jnp.where(steered, p[:, 0], 1.0))
    return fx._replace(polarise=fx.polarise | steered, polarity=jnp.where(steered, angle, fx.polarity))
