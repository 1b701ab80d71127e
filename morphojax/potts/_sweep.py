"""The compiled Metropolis loop of the cellular Potts model: copy attempts in parallel on
four sub-lattices.

Colouring. Site (i, j) has colour 2 (i mod 2) + (j mod 2); a sub-sweep makes one copy
attempt at every site of one colour, and one Monte Carlo step (MCS) runs the four colours
once each, in a random order: as many attempts as lattice sites. A copy attempt at target x
writes x only, and its energy change reads the ids of x's neighbours (order 1: the four
nearest; order 2: the eight of the Moore neighbourhood) and the volumes of two cells. Two
sites of one colour are never neighbours (their Chebyshev distance is even and >= 2), so no
attempt writes a site another simultaneous attempt reads: the contact energy of the
accepted set changes by exactly the sum of their changes, as if they ran one after another.
Sharing a neighbour is harmless, because neighbours are only read. (Disjoint closed
neighbourhoods, the stricter rule, would need nine colours for order 2 and buys nothing.)

Volumes. The volume term couples every site of one cell, so after the Metropolis tests at
most one accepted change per cell id is applied in a sub-sweep: the one with the highest
random priority among the accepted attempts that touch that id (as target's old cell or as
the copied cell; the medium has no volume term and no limit). The priorities are unique
(random high bits, the site's index in the low bits), so the choice is deterministic for a
key, and each applied change was priced against the volumes it actually changes.

Random numbers. Each MCS draws 64 bits from its `jax.random` key (fold_in(key, m)); every
site's direction, acceptance uniform and priority are a counter-based hash of those bits and
(colour, stream, site): two rounds of Wellons' lowbias32, a bijective integer hash. On XLA:CPU
a threefry draw per site costs more than the whole copy attempt; the hash is a few fused
integer operations. Every random number depends on the key, the MCS, the colour and the site
only: same key, same run.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

ORDER1 = ((-1, 0), (1, 0), (0, -1), (0, 1))
NEIGHBOURS = {1: ORDER1, 2: ORDER1 + ((-1, -1), (-1, 1), (1, -1), (1, 1))}
HALF = {1: ((0, 1), (1, 0)), 2: ((0, 1), (1, 0), (1, 1), (1, -1))}  # each unordered pair once
OUTSIDE = -1  # id of the sites beyond a fixed boundary: no energy, never copied, never written


def to_colour_major(lattice):
    """(rows, cols) with even sides -> (2, 2, rows/2, cols/2): plane [a, b] holds the sites
    (2p + a, 2q + b), the sites of colour 2a + b."""
    rows, cols = lattice.shape
    return lattice.reshape(rows // 2, 2, cols // 2, 2).transpose(1, 3, 0, 2)


def from_colour_major(planes):
    """The inverse of `to_colour_major`."""
    _, _, h, w = planes.shape
    return planes.transpose(2, 0, 3, 1).reshape(2 * h, 2 * w)


def even_lattice(ids, boundary: str):
    """`ids` padded with OUTSIDE to even sides (fixed boundary), the working lattice."""
    rows, cols = ids.shape
    if boundary == "wrap":
        return ids
    return jnp.pad(ids, ((0, rows % 2), (0, cols % 2)), constant_values=OUTSIDE)


def _neighbours(planes, a, b, order: int, boundary: str):
    """(n, h, w): the ids of the n neighbours of every site of colour (a, b)."""
    _, _, h, w = planes.shape
    if boundary == "wrap":
        halo = jnp.pad(planes, ((0, 0), (0, 0), (1, 1), (1, 1)), mode="wrap")
    else:
        halo = jnp.pad(planes, ((0, 0), (0, 0), (1, 1), (1, 1)), constant_values=OUTSIDE)
    out = []
    for di, dj in NEIGHBOURS[order]:
        # row 2p + a + di lies in plane (a + di) mod 2 at p + floor((a + di) / 2)
        ra, rb = a + di, b + dj
        start = (ra % 2, rb % 2, 1 + jnp.floor_divide(ra, 2), 1 + jnp.floor_divide(rb, 2))
        out.append(jax.lax.dynamic_slice(halo, start, (1, 1, h, w))[0, 0])
    return jnp.stack(out)


def attempt_energy(model, old, src, nbs, types, volumes):
    """The energy change of copying `src` onto sites holding `old` (the Hamiltonian of
    Tinson 2022, section III.B: contact over the neighbours `nbs`, volume of both cells)."""
    J = model.J
    t_old, t_src = types[jnp.maximum(old, 0)], types[jnp.maximum(src, 0)]
    t_nb = types[jnp.maximum(nbs, 0)]
    inside = nbs != OUTSIDE
    contact = jnp.where(inside, J[t_src[None], t_nb] * (src[None] != nbs) - J[t_old[None], t_nb] * (old[None] != nbs),
                        0.0).sum(0)
    lam, target = model.volume_weight, model.target_volume
    v_old = volumes[jnp.maximum(old, 0)].astype(contact.dtype)
    v_src = volumes[jnp.maximum(src, 0)].astype(contact.dtype)
    # lam ((v - 1 - V)^2 - (v - V)^2) for the shrinking cell, lam ((v + 1 - V)^2 - (v - V)^2) for the growing one
    shrink = jnp.where(old > 0, lam * (1.0 - 2.0 * (v_old - target)), 0.0)
    grow = jnp.where(src > 0, lam * (1.0 + 2.0 * (v_src - target)), 0.0)
    return contact + shrink + grow


def _lowbias32(x):
    """Wellons' lowbias32: a bijective hash of uint32 with good avalanche."""
    x = x ^ (x >> 16)
    x = x * jnp.uint32(0x7FEB352D)
    x = x ^ (x >> 15)
    x = x * jnp.uint32(0x846CA68B)
    return x ^ (x >> 16)


def site_bits(seed, colour, stream, shape):
    """uint32 random words for every site of a sub-sweep: hash(hash(counter + seed[0]) ^ seed[1])
    with counter = site + sites (3 colour + stream)."""
    n = shape[0] * shape[1]
    counter = jnp.arange(n, dtype=jnp.uint32).reshape(shape) + jnp.uint32(n) * (
        jnp.uint32(3) * colour.astype(jnp.uint32) + jnp.uint32(stream))
    return _lowbias32(_lowbias32(counter + seed[0]) ^ seed[1])


def sub_sweep(model, planes, volumes, types, seed, colour):
    """One copy attempt at every site of `colour` (random words from the two uint32 of
    `seed`); returns (planes, volumes, energy change, accepted attempts)."""
    _, _, h, w = planes.shape
    colour = jnp.asarray(colour, jnp.int32)
    a, b = colour // 2, colour % 2
    nbs = _neighbours(planes, a, b, model.order, model.boundary)
    n_nb = nbs.shape[0]  # 4 or 8: the top bits pick the source
    direction = (site_bits(seed, colour, 0, (h, w)) >> (32 - n_nb.bit_length() + 1)).astype(jnp.int32)
    old = jax.lax.dynamic_slice(planes, (a, b, 0, 0), (1, 1, h, w))[0, 0]
    src = jnp.take_along_axis(nbs, direction[None], 0)[0]
    active = (old != OUTSIDE) & (src != OUTSIDE) & (src != old)
    d_h = attempt_energy(model, old, src, nbs, types, volumes)
    temperature = model.temperature
    boltzmann = jnp.where(temperature > 0, jnp.exp(-d_h / jnp.where(temperature > 0, temperature, 1.0)), 0.0)
    u = (site_bits(seed, colour, 1, (h, w)) >> 8).astype(d_h.dtype) * (2.0 ** -24)  # [0, 1)
    accepted = active & ((d_h <= 0) | (u < boltzmann))
    # unique priorities: random high bits, the site's index in the low bits
    low = max(1, int(np.ceil(np.log2(h * w))))
    bits = site_bits(seed, colour, 2, (h, w))
    priority = ((bits >> low) << low) | jnp.arange(h * w, dtype=jnp.uint32).reshape(h, w)
    touch_old, touch_src = accepted & (old > 0), accepted & (src > 0)
    best = jnp.zeros(volumes.shape, jnp.uint32)
    best = best.at[jnp.where(touch_old, old, 0)].max(jnp.where(touch_old, priority, 0))
    best = best.at[jnp.where(touch_src, src, 0)].max(jnp.where(touch_src, priority, 0))
    applied = (accepted & ((old <= 0) | (best[jnp.maximum(old, 0)] == priority))
               & ((src <= 0) | (best[jnp.maximum(src, 0)] == priority)))
    new = jnp.where(applied, src, old)
    planes = jax.lax.dynamic_update_slice(planes, new[None, None], (a, b, 0, 0))
    one = applied.astype(volumes.dtype)
    volumes = volumes.at[jnp.where(applied, old, 0)].add(-one).at[jnp.where(applied, src, 0)].add(one)
    return planes, volumes, jnp.where(applied, d_h, 0.0).sum(), applied.sum()


def one_mcs(model, planes, volumes, types, key, m):
    """Monte Carlo step `m`: the four colours in an order drawn from fold_in(key, m); returns
    (planes, volumes, energy change, accepted attempts)."""
    k_order, k_seed = jax.random.split(jax.random.fold_in(key, m))
    order = jax.random.permutation(k_order, 4)
    seed = jax.random.bits(k_seed, (2,), jnp.uint32)

    def one_colour(carry, colour):
        planes, volumes = carry
        planes, volumes, d_e, n = sub_sweep(model, planes, volumes, types, seed, colour)
        return (planes, volumes), (d_e, n)

    (planes, volumes), (d_e, n) = jax.lax.scan(one_colour, (planes, volumes), order)
    return planes, volumes, d_e.sum(), n.sum()


def run_mcs(model, planes, volumes, types, key, mcs: int):
    """`mcs` (static) Monte Carlo steps; returns (planes, volumes, energy change per MCS,
    accepted attempts per MCS)."""

    def body(carry, m):
        planes, volumes, d_e, n = one_mcs(model, *carry, types, key, m)
        return (planes, volumes), (d_e, n)

    (planes, volumes), (d_e, n) = jax.lax.scan(body, (planes, volumes), jnp.arange(mcs))
    return planes, volumes, d_e, n


def run_mcs_dynamic(model, planes, volumes, types, key, mcs):
    """`mcs` (a traced integer: one compiled loop for every count) Monte Carlo steps, the
    same steps as `run_mcs`; returns (planes, volumes)."""

    def body(m, carry):
        return one_mcs(model, *carry, types, key, m)[:2]

    return jax.lax.fori_loop(0, mcs, body, (planes, volumes))


def total_energy(model, ids, types, volumes):
    """Tinson's (2022) Hamiltonian of a lattice: J(type, type') over every unordered pair of
    neighbouring sites in different cells, plus lambda (v - V)^2 over the cells 1..n."""
    t = types[ids]
    contact = jnp.zeros((), model.J.dtype)
    rows, cols = ids.shape
    for di, dj in HALF[model.order]:
        if model.boundary == "wrap":
            nb, tn, a, ta = jnp.roll(ids, (-di, -dj), (0, 1)), jnp.roll(t, (-di, -dj), (0, 1)), ids, t
        else:  # pairs (x, x + d) with both inside
            i0, i1 = 0, rows - di
            j0, j1 = max(0, -dj), cols - max(0, dj)
            a, ta = ids[i0:i1, j0:j1], t[i0:i1, j0:j1]
            nb, tn = ids[i0 + di:i1 + di, j0 + dj:j1 + dj], t[i0 + di:i1 + di, j0 + dj:j1 + dj]
        contact = contact + jnp.where(a != nb, model.J[ta, tn], 0.0).sum()
    v = volumes[1:].astype(model.J.dtype)
    return contact + model.volume_weight * ((v - model.target_volume) ** 2).sum()
