"""The one compiled loop every automaton runs in, and what it returns.

`iterate` applies a one-step function `steps` times: a `lax.scan`, or a `lax.while_loop`
that stops at convergence. A stepper may carry the lattice in another form than the
integer cells (a `Codec`: the direct sums carry it widened, the FFT of one species its
float indicator); frames and changed cells are always taken on the decoded lattice.
"""

from __future__ import annotations

from typing import Callable, NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
from jax import Array


class AutomatonRun(eqx.Module):
    """What `run` returns.

    cells: the final lattice. steps: the number of updates applied. converged: whether
    the last update changed fewer than `threshold` of the cells. changes (with
    `history=True`, else None): the fraction of cells changed by each update, shape
    (steps requested,), NaN after an early stop. frames / frame_steps (with `save_every`,
    else None): the lattice every `save_every` updates (frame 0 is the start) and the
    update count of each frame (-1 for frames not reached before an early stop).
    """

    cells: Array
    steps: Array
    converged: Array
    changes: Array | None = None
    frames: Array | None = None
    frame_steps: Array | None = None


class Codec(NamedTuple):
    """How a stepper carries the lattice through the loop: `encode` maps integer cells
    to the carried form (which may be wider than the lattice) and `decode` maps it back
    to the cells, of `dtype` (decode(encode(c)) == c; changed cells are counted on the
    decoded lattice)."""

    encode: Callable
    decode: Callable


def identity_codec(dtype) -> Codec:
    """The lattice carried as itself (cast back to `dtype` on decoding)."""
    return Codec(lambda c: c, lambda c: c.astype(dtype))


def iterate(step_fn: Callable, cells, steps: int, stop: bool, threshold, save_every: int | None,
            history: bool, codec: Codec | None = None) -> AutomatonRun:
    """Apply `step_fn` `steps` times in one compiled loop: a `lax.scan`, or a
    `lax.while_loop` that stops at convergence when `stop`. `step_fn` works on the
    carried form of `codec` (default: the integer cells themselves)."""
    codec = identity_codec(cells.dtype) if codec is None else codec
    dtype, shape, cells = cells.dtype, cells.shape, codec.encode(cells)
    # "last": the changed fraction of the latest update. A plain run counts it in its final
    # update only (the first steps - 1 run in a lean scan: no count, no copy of the lattice)
    carry = {"i": jnp.int32(0), "cells": cells, "last": jnp.float32(1.0)}
    if history:
        carry["changes"] = jnp.full((steps,), jnp.nan, jnp.float32)
    if save_every:
        n_frames = steps // save_every + 1
        carry["frames"] = jnp.zeros((n_frames,) + shape, dtype).at[0].set(codec.decode(cells))
        carry["frame_steps"] = jnp.full((n_frames,), -1, jnp.int32).at[0].set(0)

    def body(carry, count=True):
        carry = dict(carry)
        i, c = carry["i"], carry["cells"]
        new = step_fn(c)
        if count:
            carry["last"] = frac = jnp.mean(codec.decode(new) != codec.decode(c)).astype(jnp.float32)
            if history:
                carry["changes"] = carry["changes"].at[i].set(frac)
        i = i + 1
        if save_every:
            slot, save = i // save_every, (i % save_every) == 0
            carry["frames"] = carry["frames"].at[slot].set(jnp.where(save, codec.decode(new), carry["frames"][slot]))
            carry["frame_steps"] = carry["frame_steps"].at[slot].set(jnp.where(save, i, carry["frame_steps"][slot]))
        carry.update(i=i, cells=new)
        return carry

    if steps > 0 and stop:
        carry = jax.lax.while_loop(lambda c: (c["i"] < steps) & (c["last"] >= threshold), body, carry)
    elif steps > 0:
        lean = steps - 1 if not history else 0
        if lean:
            carry = jax.lax.scan(lambda c, _: (body(c, count=False), None), carry, None, length=lean)[0]
        carry = jax.lax.scan(lambda c, _: (body(c), None), carry, None, length=steps - lean)[0]
    converged = (carry["last"] < threshold) & (carry["i"] > 0)
    return AutomatonRun(codec.decode(carry["cells"]), carry["i"], converged, carry.get("changes"),
                        carry.get("frames"), carry.get("frame_steps"))
