"""Member lanes: a group of a sweep's members stepped as one array, one member per vector lane.

One small lattice keeps a CPU core's vector units half idle: each step's loops run over the
cells of one member. The members of a sweep run the same arithmetic on lattices of the same
shape and differ only in their parameter values, so a group of them is laid out as one array
(species, rows, cols, members) with the member axis last, innermost in memory: every
operation of the step (the stencil's shifted reads, the reaction, the clamp) then works on
whole vectors of members, and each parameter is a (1, members) map that meets them lane by
lane. The step is the same (`make_step`); each member's numbers agree with a lone run's to
float rounding, not bit for bit (XLA compiles a (1, members) parameter differently from a
scalar one), and since a group always holds the same number of members, they do not depend
on the chunking or on a member's place in its group.

The layout applies where every member's step is pointwise in its parameters and free of
randomness: a square lattice (the sweep's), a built-in model whose parameters are scalars or
per-species vectors (no parameter maps; a user's `Reaction` function is promised plain
(species, rows, cols) arrays, and a `Modulated` model makes maps from the state), no growth,
no sources (`lanes_apply`). A group checks its members for non-finite values where a lone
run does (`default_chunk`), but only flags them: the sweep re-runs a flagged group member by
member to find the exact first bad step.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ._bounds import bounds_policy
from ._descriptors import relative_change
from ._loop import _scan, default_chunk
from ._step import Carry, Config, make_step
from ._sweep_members import member_model
from .domains import AbstractDomain, _stencils
from .models import Composite, Modulated, Reaction

# Members per group: one vector register of the host CPU's widest common width (AVX2, 32
# bytes), 8 float32 or 4 float64 members; 16 and 32 measured slower (figures in
# benchmarks/results/bench_sweep.md).
VECTOR_BYTES = 32
NOT_LOCATED = -2  # a member's `bad` when a group flagged it and the sweep must re-run it alone


def lane_count(dtype) -> int:
    """Members per group for fields of `dtype`."""
    return max(1, VECTOR_BYTES // np.dtype(dtype).itemsize)


def _plain_layout_only(model) -> bool:
    """A user's function (promised plain arrays) or parameters computed from the state."""
    if isinstance(model, Composite):
        return any(map(_plain_layout_only, model.parts))
    return isinstance(model, (Reaction, Modulated))


def lanes_apply(model, growth, sources, probe) -> bool:
    """Whether a sweep's members can run in lanes (see the module's docstring)."""
    if growth is not None or sources or probe.growable or _plain_layout_only(model):
        return False
    return all(jnp.ndim(leaf) <= 1 for leaf in jax.tree_util.tree_leaves(eqx.filter(model, eqx.is_array)))


class _LaneLattice(AbstractDomain):
    """The square lattice with fields (species, rows, cols, members): the stencil on the rows
    and columns, each member's ghost cells its own. Scalar (per-member) rates only."""

    stencil: str = eqx.field(static=True)
    boundary: str = eqx.field(static=True)

    @property
    def spectral_radius(self) -> float:
        return _stencils.SPECTRAL_RADIUS[self.stencil]

    @property
    def ndim(self) -> int:
        return 3  # rows, cols, members: a (species,) value broadcasts as (species, 1, 1, 1)

    @property
    def description(self) -> str:
        return f"{self.stencil} stencil, members in lanes"

    @property
    def supports_growth(self) -> bool:
        return False

    def carry(self, fields, size, dynamic):
        return _stencils.pad(fields, self.boundary, lanes=True)

    def interior(self, carried):
        return carried[:, 1:-1, 1:-1, :]

    def diffusion(self, carried, rates):
        lap = _stencils.laplacian_padded(carried, self.stencil, lanes=True)
        return [rates[i] * lap[i] for i in range(carried.shape[0])]

    def write(self, carried, new, size, dynamic):
        return _stencils.pad(new, self.boundary, lanes=True)

    def active_mask(self, shape, size):
        raise NotImplementedError("members in lanes never have an active region smaller than the lattice")

    def apply(self, fields):
        return _stencils.laplacian_padded(_stencils.pad(fields, self.boundary, lanes=True), self.stencil, lanes=True)


def _lane_model(model, dt, values):
    """The group's model and dt. Each array leaf of shape s (a scalar or a per-species vector)
    becomes (*s, 1, members): to the model's own code a (1, members) parameter map, which
    broadcasts against a species' (rows, cols, members) lanes member by member."""
    def one(v):
        m, _, d = member_model(model, None, dt, v)
        return m, d

    m, d = eqx.filter_vmap(one)(values)
    lanes = lambda x: jnp.moveaxis(x, 0, -1)[..., None, :] if eqx.is_array(x) else x  # noqa: E731
    return jax.tree_util.tree_map(lanes, m), d


def _advance(step, c: Carry, n: int, flagged):
    """`n` steps, checking each member for non-finite values where a lone run would."""
    per = default_chunk(n, None)

    def chunk(carry, k):
        c, flagged = carry
        c = _scan(step, c, k)
        return c, flagged | ~jnp.all(jnp.isfinite(c.p), axis=(0, 1, 2))

    full, rem = divmod(n, per)
    if full:
        (c, flagged), _ = jax.lax.scan(lambda s, _: (chunk(s, per), None), (c, flagged), None, length=full)
    if rem:
        c, flagged = chunk((c, flagged), rem)
    return c, flagged


def run_group(model, fields, size, step0, values, dt, *, steps, tail, boundary, stencil, bounds):
    """A group of members in lanes: (fields (members, species, rows, cols), size (members, 2),
    bad step (-1 or NOT_LOCATED), overflow, change over the last `tail` steps), the same
    outputs as a lone run's per member. `fields`: (members, species, rows, cols), or
    (species, rows, cols) shared by every member; `size` and `step0` those of every start."""
    members = len(next(iter(values.values())))
    m, dt = _lane_model(model, dt, values)
    dtype = fields.dtype
    x = (jnp.broadcast_to(fields[..., None], fields.shape + (members,)) if fields.ndim == 3
         else jnp.moveaxis(fields, 0, -1))
    domain = _LaneLattice(stencil, boundary)
    step = make_step(m, domain, dt.astype(dtype), Config(bounds=bounds_policy(bounds), dynamic=False), None, (),
                     None, step0)
    c = Carry(domain.carry(x, size, False), size, step0, jnp.asarray(-1, jnp.int32), jnp.asarray(False))
    flagged = jnp.zeros(members, bool)
    c, flagged = _advance(step, c, steps - tail, flagged)
    change = jnp.full(members, jnp.nan, dtype)
    if tail:
        mid = domain.interior(c.p)
        c, flagged = _advance(step, c, tail, flagged)
        change = jax.vmap(lambda a, b: relative_change(a, b, xp=jnp), in_axes=(-1, -1))(mid, domain.interior(c.p))
    final = jnp.moveaxis(domain.interior(c.p), -1, 0)
    bad = jnp.where(flagged, NOT_LOCATED, -1)
    return final, jnp.broadcast_to(size, (members, 2)), bad, jnp.zeros(members, bool), change
