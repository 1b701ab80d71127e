"""Initial conditions ("prepatterns"), seeded by a `jax.random` key.

The leopard paper (section 7.1) uses two kinds: A constant 4 with B uniform in [4, 5),
and a fully constant state (A = B = 4) where randomness comes later from localised
production and cell division. The thesis uses a mean and a deviation per species
(uniform in [mean - dev, mean + dev)).

A shape is (rows, cols) for a lattice, or (vertices,) for a mesh (one value per vertex, in
the mesh's vertex order); room to grow (`capacity`) exists on lattices only.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp

from ._checks import cells_of, check_finite, check_memory, check_range, check_shape, default_float
from ._state import State


def _spatial(shape, capacity=None) -> tuple:
    """(rows, cols), (vertices,) or a 3D lattice's (depth, rows, cols), checked."""
    if isinstance(shape, (str, bytes)) or not hasattr(shape, "__len__"):
        raise ValueError(f"shape must be (rows, cols), (vertices,) for a mesh or (depth, rows, cols) (got {shape!r})")
    out = check_shape(shape, "shape")  # whole numbers: (16.5, 16) is refused, not floored
    if capacity is not None:
        check_shape(capacity, "capacity")
    check_memory(cells_of(capacity if capacity is not None else out) * 4 * 4, "this initial state")
    if len(out) not in (1, 2, 3):
        raise ValueError(f"shape must be (rows, cols), (vertices,) for a mesh or (depth, rows, cols) (got {shape!r})")
    if min(out) < 1:
        raise ValueError(f"shape must be at least {(1,) * len(out)} (got {out})")
    if capacity is not None and len(out) != 2:
        raise ValueError(f"capacity (room to grow) needs a (rows, cols) lattice (got shape {out})")
    return out


def random_state(key, shape, *species, names=None, capacity=None) -> State:
    """A state with one entry per species: a constant, or a (low, high) uniform range.

    `random_state(key, (100, 100), 4.0, (4.0, 5.0))` is the paper's A = 4, B ~ U[4, 5);
    `shape=(vertices,)` gives one value per vertex of a mesh. Each species draws from its
    own sub-key, so adding a species does not change the others.
    """
    shape = _spatial(shape, capacity)
    if not species:
        raise ValueError("random_state needs at least one species specification")
    dtype = default_float()
    arrays = []
    for i, spec in enumerate(species):
        if isinstance(spec, (tuple, list)):
            if len(spec) != 2:
                raise ValueError(f"species {i}: a range must be (low, high) (got {spec!r})")
            lo, hi = (float(v) for v in spec)
            check_finite(lo, f"species {i} low")
            check_finite(hi, f"species {i} high")
            check_range(hi, f"species {i} high", low=lo)
            arrays.append(jax.random.uniform(jax.random.fold_in(key, i), shape, dtype, lo, hi))
        else:
            check_finite(spec, f"species {i} value")
            arrays.append(jnp.full(shape, spec, dtype))
    return State.from_arrays(arrays, capacity=capacity, names=names)


def constant_state(shape, *values, names=None, capacity=None) -> State:
    """A state where every species is constant (the paper's A = B = 4 prepattern)."""
    return random_state(jax.random.key(0), shape, *values, names=names, capacity=capacity)


def paper_state(key, shape, capacity=None) -> State:
    """The leopard paper's usual start: A = 4 everywhere, B uniform in [4, 5)."""
    return random_state(key, shape, 4.0, (4.0, 5.0), names=("a", "b"), capacity=capacity)


def thesis_state(key, shape, dev=2.0, mean=4.0, capacity=None) -> State:
    """The thesis's `conc 4 dev 2` start: both species uniform in [mean - dev, mean + dev)."""
    return random_state(key, shape, (mean - dev, mean + dev), (mean - dev, mean + dev), names=("a", "b"),
                        capacity=capacity)


def gray_scott_state(key, shape, square=0.2, noise=0.02, capacity=None, *, seeded=None) -> State:
    """Pearson's start for Gray-Scott: u = 1, v = 0, a central square (a cube on a 3D
    lattice) at (u, v) = (0.5, 0.25), plus uniform noise of amplitude `noise`. `square` is
    the side as a fraction of the lattice.

    On a mesh (`shape=(vertices,)`), where the vertex order says nothing about position, the
    perturbed patch is given instead: `seeded`, the indices of its vertices (the mesh
    presets' `seed_patches(mesh)`)."""
    shape = _spatial(shape, capacity)
    dtype = default_float()
    if len(shape) == 1:
        if seeded is None:
            raise ValueError("gray_scott_state on a mesh (shape=(vertices,)) needs seeded=: the indices of the "
                             "vertices to perturb, e.g. morphojax.presets._meshes.seed_patches(mesh)")
        seeded = jnp.asarray(seeded, jnp.int32).reshape(-1)
        if seeded.size and (int(seeded.min()) < 0 or int(seeded.max()) >= shape[0]):
            raise ValueError(f"seeded must hold vertex indices in [0, {shape[0] - 1}] "
                             f"(got {int(seeded.min())}..{int(seeded.max())})")
        patch = jnp.zeros(shape, bool).at[seeded].set(True)
    else:
        if seeded is not None:
            raise ValueError("seeded= is for meshes (shape=(vertices,)); on a lattice the patch is the central "
                             "square of side `square`")
        # the central square (a cube in 3D) of side `square` times the lattice's
        half = [max(1, int(n * square) // 2) for n in shape]
        patch = jnp.zeros(shape, bool).at[tuple(slice(n // 2 - h, n // 2 + h) for n, h in zip(shape, half))].set(True)
    u = jnp.where(patch, 0.5, 1.0).astype(dtype)
    v = jnp.where(patch, 0.25, 0.0).astype(dtype)
    ku, kv = jax.random.split(key)
    u = jnp.clip(u + noise * jax.random.uniform(ku, shape, dtype, -1.0, 1.0), 0.0, 1.0)
    v = jnp.clip(v + noise * jax.random.uniform(kv, shape, dtype, -1.0, 1.0), 0.0, 1.0)
    return State.from_arrays([u, v], capacity=capacity, names=("u", "v"))


STEADY_NOISE = 0.01  # relative half-width of the noise around a homogeneous state


def around(value: float, noise: float = STEADY_NOISE) -> tuple[float, float]:
    """The uniform range `value` +- noise max(|value|, 1): a homogeneous state with small
    noise (absolute near 0, where a relative range would vanish)."""
    spread = noise * max(abs(value), 1.0)
    return (value - spread, value + spread)


def initial_state(model, key, shape, capacity=None) -> State:
    """The customary random start for `model`: see `paper_state`, `gray_scott_state`.

    Reinforcement starts uniform in [t - w, t + w); the classic reactions (FitzHugh-Nagumo,
    Gierer-Meinhardt, Schnakenberg, Brusselator, Thomas) at their homogeneous state with `around`'s
    noise; the thesis's reinforcement rules uniform between their limits (the thesis's
    `conc 0.5 dev 0.5`); composites stack their parts' starts.
    """
    from .models import (Bard, Brusselator, Composite, FitzHughNagumo, GiererMeinhardt, GrayScott, Reinforcement,
                         RuleReinforcement, Schnakenberg, ThesisReinforcement, Thomas, Turing)

    if isinstance(model, Turing):
        return paper_state(key, shape, capacity)
    if isinstance(model, Bard):
        return thesis_state(key, shape, capacity=capacity)
    if isinstance(model, GrayScott):
        return gray_scott_state(key, shape, capacity=capacity)
    if isinstance(model, Reinforcement):
        t, w = float(jnp.max(model.threshold)), float(jnp.max(model.width))
        return random_state(key, shape, (t - w, t + w), names=("c",), capacity=capacity)
    if isinstance(model, (FitzHughNagumo, GiererMeinhardt, Schnakenberg, Brusselator, Thomas)):
        # the classic reactions: their steady state, a little noise
        steady = [float(jnp.max(v)) for v in model.homogeneous_state()]
        return random_state(key, shape, *(around(v) for v in steady), names=model.species, capacity=capacity)
    if isinstance(model, (ThesisReinforcement, RuleReinforcement)):  # uniform between the limits, as the thesis
        lo, hi = float(jnp.min(model.lower)), float(jnp.max(model.upper))
        lo, hi = (lo, hi) if math.isfinite(lo) and math.isfinite(hi) else (0.0, 1.0)
        return random_state(key, shape, (lo, hi), names=model.species, capacity=capacity)
    if isinstance(model, Composite):
        parts = [initial_state(p, jax.random.fold_in(key, i), shape, capacity) for i, p in enumerate(model.parts)]
        fields = jnp.concatenate([p.fields for p in parts])
        return State(fields, parts[0].size, names=model.species)
    raise ValueError(f"no default initial state for {type(model).__name__}; build one with random_state")
