"""Young's activator-inhibitor cellular automaton in any dimension, with K species.

Cells hold an integer state: 0 .. K-1 are the K differentiated species and K is the
undifferentiated state (for Young's original K = 1: 0 = differentiated, 1 = not; note
that this is the reverse of the 0/1 coding in the Python code of Tinson 2022, use
`1 - cells` to convert). Species j has an activator neighbourhood of radius r_act[j]
with weight w_act[j] and an inhibitor ring r_act[j] < d <= r_inh[j] with weight
w_inh[j] < 0, the activator counting for more than the ring: w_act[j] > w_inh[j]
(usually w_act[j] > 0; see `YoungCA` for the weights <= 0 Tinson's code gives). Its net
field at a cell is

    W_j = w_act[j] * (# cells of species j in the activator disc)
        + w_inh[j] * (# cells of species j in the inhibitor ring)

and the synchronous update (Dur 2023, eqs. 1-4) is: the species with the largest W_j
wins when that maximum is > 0 (the lowest index on a tie between species), the cell
becomes undifferentiated when the maximum is < 0, and keeps its state when it is 0.

Units and conventions:
- radii are in lattice cells (Euclidean distance for `neighbourhood="disc"`, the
  Chebyshev distance max|dx_i| for Young's square boxes, `"box"` (Moore's), the
  Manhattan distance sum|dx_i| for von Neumann's diamonds, `"diamond"`); an offset at squared
  distance d2 belongs to the disc of radius r when d2 <= r^2 (1 + 1e-6), so a radius
  typed as 3 or 1.4142135 includes the shell at exactly that distance (`_geometry`);
- the cell itself is not a neighbour unless `include_self=True` (then it counts in the
  activator disc, as in Young's code);
- boundaries are periodic and every side of the lattice must be at least
  2 floor(r_inh) + 1 cells, so that no neighbour is counted twice;
- weights are compared exactly: they are read as fractions over a common `denominator`
  (by default the smallest one that makes every weight's shortest decimal form an
  integer, e.g. 5 for 1 and -0.2) and the fields are computed as integers, so a tie such
  as 3 x 1 + 15 x (-0.2) = 0 is an exact zero and keeps the state.

Neighbour counts are exact integers, computed by byte sums of shifted slices of a
periodically padded copy (`method="direct"`, `_direct`: fastest for Young's radii), by
FFT convolution with kernel spectra computed once per run (`method="fft"`, `_fft`:
fastest for large radii, and the only method for traced radii), or by real separable
Fourier transforms as matrix products (`method="matmul"`, `_matmul`: small 3D lattices on
CPU); the last two are rounded to integers. `method="auto"` picks the cheapest from a
cost model (`_choice`); all give identical results. The differentiable relaxation lives
in `_soft`.
"""

from __future__ import annotations

import functools
import math
from fractions import Fraction

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from .._checks import check_choice, check_range, is_concrete
from ._base import AbstractAutomaton, call
from ._caches import SPECTRA_MAX_SIZE, cached_plan, cached_spectra, freeze
from ._choice import YoungPlan, make_plan
from ._direct import direct_fields, widen
from ._fft import fft_convolve, fft_counts, fft_spectra
from ._geometry import NEIGHBOURHOODS, ball_size, neighbourhood_kernels, threshold
from ._loop import Codec, identity_codec
from ._matmul import matmul_convolve, matmul_spectra
from ._soft import soft_run, soft_step

METHODS = ("auto", "direct", "fft", "matmul")
MAX_DENOMINATOR = 10**6


# ---- exact weights -----------------------------------------------------------------------
def decimal_fraction(value) -> Fraction:
    """The shortest decimal that rounds to `value` in its own precision, as a Fraction."""
    return Fraction(np.format_float_positional(value, unique=True, trim="0"))


def common_denominator(values) -> int:
    """The smallest denominator that makes every value's shortest decimal an integer."""
    den = 1
    for v in np.asarray(values).ravel():
        den = math.lcm(den, decimal_fraction(v).denominator)
    return den


# ---- the automaton -----------------------------------------------------------------------
class YoungCA(AbstractAutomaton):
    """Young's activator-inhibitor automaton with K species (Dur 2023 eqs. 1-4).

        ca = YoungCA(species=[(3.2, 6.0, 1.0, -0.2)])        # (r_act, r_inh, w_act, w_inh)
        cells = random_cells(jax.random.key(0), (30, 30, 30), k=1, p=None)
        out = ca.run(cells, 100, stop_at_convergence=True)   # out.cells, out.steps

    Radii are in lattice cells; weights are the net field of one differentiated cell in the
    activator disc (w_act) and in the inhibitor ring (w_inh < 0). `neighbourhood` is "disc"
    (Euclidean, Dur 2023), "box" (Young's square boxes as in Tinson's (2022) code, Moore's
    neighbourhood) or "diamond" (von Neumann's, Tinson's (2022) Fig. 1 (b)); `include_self`
    counts the cell itself in its activator disc. Tinson's (2022) code, which sums the
    inhibitor over the whole box (self included) and writes WS = Na wa - Ni wi, is
    `YoungCA([(Ra, Ri, wa - wi, -wi)], "box", include_self=True)`.

    The rule on the weights is the code's wa > 0 and wi > 0: w_inh < 0 and w_act > w_inh
    (the disc counts for more than the ring). w_act itself may be 0 or negative: Tinson's
    Appendix B2 runs wi = 1.00 and 1.05 at wa = 1, a disc weight of 0 and -0.05. A species
    with w_act <= 0 has no field > 0 anywhere, so it never wins a cell: with one species,
    a cell with a differentiated cell in its ring (with w_act < 0: anywhere in its disc or ring)
    becomes undifferentiated and every other cell keeps its state. w_act <= w_inh (the
    code's wa <= 0: no activation at all) is refused.

    The radii and weights are float array leaves of shape (K,), so a model can be
    vmapped over (stack several models, or build it inside vmap with an explicit
    `denominator`), and the soft relaxation `soft_step` is differentiable in all of them.
    `denominator` (an integer leaf) is the common denominator the weights are compared
    over, exactly, as the integers round(w x denominator); by default the smallest one for
    the weights' decimal forms (at most 10^6). `method` picks the counting ("auto",
    "direct", "fft" or "matmul"; all exact and identical).
    """

    r_act: Array
    r_inh: Array
    w_act: Array
    w_inh: Array
    denominator: Array
    neighbourhood: str = eqx.field(static=True)
    include_self: bool = eqx.field(static=True)
    method: str = eqx.field(static=True)

    def __init__(self, species, neighbourhood: str = "disc", include_self: bool = False, *,
                 denominator=None, method: str = "auto"):
        dtype = jnp.result_type(float)
        # Python or NumPy numbers are read on the host, so that the default denominator can
        # be worked out even when the model is built inside jit / vmap
        host = not any(isinstance(leaf, jax.Array) for leaf in jax.tree_util.tree_leaves(species))
        xp = np if host else jnp
        if isinstance(species, (list, tuple)):
            if len(species) == 0:
                raise ValueError("YoungCA.species needs at least one (r_act, r_inh, w_act, w_inh) tuple")
            rows = []
            for i, sp in enumerate(species):
                if not isinstance(sp, (list, tuple, np.ndarray, jax.Array)) or len(sp) != 4:
                    raise ValueError(f"YoungCA.species[{i}] must be a tuple (r_act, r_inh, w_act, w_inh) (got {sp!r})")
                rows.append(xp.stack([xp.asarray(v, dtype=dtype) for v in sp]))
            table = xp.stack(rows)
        else:
            table = xp.asarray(species, dtype=dtype)
            if table.ndim != 2 or table.shape[1] != 4:
                raise ValueError(f"YoungCA.species must have shape (K, 4) (got {table.shape})")
        self.r_act, self.r_inh, self.w_act, self.w_inh = (jnp.asarray(table[:, i]) for i in range(4))
        check_choice(neighbourhood, "YoungCA.neighbourhood", NEIGHBOURHOODS)
        check_choice(method, "YoungCA.method", METHODS)
        self.neighbourhood = neighbourhood
        self.include_self = bool(include_self)
        self.method = method
        if denominator is None:
            if not (host or is_concrete(table)):
                raise ValueError(
                    "YoungCA.denominator must be given when the weights are traced (inside jit/vmap): "
                    "weights are compared exactly as integers over it, e.g. denominator=100 for two decimals"
                )
            denominator = common_denominator(np.asarray(table)[:, 2:])
            if denominator > MAX_DENOMINATOR:
                raise ValueError(
                    f"YoungCA weights must be decimals with a common denominator <= {MAX_DENOMINATOR} "
                    f"(at most 6 decimal places; got common denominator {denominator}); round them or "
                    "pass an explicit denominator="
                )
        if is_concrete(denominator) and np.any(np.asarray(denominator) != np.round(np.asarray(denominator, float))):
            raise ValueError(f"YoungCA.denominator must be a whole number (got {denominator!r})")
        self.denominator = jnp.asarray(denominator, dtype=jnp.int32)

    def __check_init__(self):
        k = self.r_act.shape[0]
        if k > 126:
            raise ValueError(f"YoungCA.species: at most 126 species (got {k})")
        for name in ("r_act", "r_inh", "w_act", "w_inh"):
            v = getattr(self, name)
            if is_concrete(v) and not np.isfinite(np.asarray(v)).all():
                raise ValueError(f"YoungCA.{name} must be finite (got {np.asarray(v)})")
        check_range(self.r_act, "YoungCA.r_act (activator radius, lattice cells)", low=0.0)
        check_range(self.w_inh, "YoungCA.w_inh (inhibitor weight)", high=0.0, high_open=True)
        if is_concrete(self.w_act, self.w_inh):
            wa, wi = np.asarray(self.w_act), np.asarray(self.w_inh)
            if (wa <= wi).any():
                j = int(np.argmax(wa <= wi))
                raise ValueError(
                    f"YoungCA.w_act (activator weight) must be > w_inh for every species (the activator disc "
                    f"counts for more than the ring; Tinson's wa = w_act - w_inh > 0); species {j} has w_act "
                    f"{wa[j]:g} <= w_inh {wi[j]:g}"
                )
        if is_concrete(self.r_act, self.r_inh):
            ra, ri = np.asarray(self.r_act), np.asarray(self.r_inh)
            if (ri < ra).any():
                j = int(np.argmax(ri < ra))
                raise ValueError(
                    f"YoungCA.r_inh (inhibitor radius, lattice cells) must lie in [r_act, +inf) for every "
                    f"species; species {j} has r_inh {ri[j]:g} < r_act {ra[j]:g}"
                )
        check_range(self.denominator, "YoungCA.denominator", low=1, high=MAX_DENOMINATOR)
        if is_concrete(self.w_act, self.w_inh, self.denominator):
            den = int(self.denominator)
            for name in ("w_act", "w_inh"):
                value = np.asarray(getattr(self, name))
                scaled = value.astype(np.float64) * den
                if (np.abs(scaled) >= 2**24).any():
                    raise ValueError(
                        f"YoungCA.{name} x denominator must stay below 2^24 in magnitude (exact in float32); "
                        f"got {value} x {den}"
                    )
                # a multiple of 1/den stored in the weights' precision is within a few of its
                # ulps of one (a looser test would round a weight such as 1000.004 to 1000)
                tol = 4.0 * float(np.finfo(value.dtype).eps) * np.maximum(1.0, np.abs(scaled))
                if (np.abs(scaled - np.round(scaled)) > tol).any():
                    raise ValueError(
                        f"YoungCA.{name} must be multiples of 1/denominator = 1/{den} (got {np.asarray(getattr(self, name))})"
                    )

    # ---- description ------------------------------------------------------------------
    @property
    def n_species(self) -> int:
        return int(self.r_act.shape[0])

    @property
    def n_states(self) -> int:
        return self.n_species + 1

    @property
    def species(self) -> list[tuple[float, float, float, float]]:
        """The (r_act, r_inh, w_act, w_inh) tuples (concrete models only)."""
        cols = [np.asarray(getattr(self, n)) for n in ("r_act", "r_inh", "w_act", "w_inh")]
        return [tuple(float(decimal_fraction(c[j])) for c in cols) for j in range(self.n_species)]

    def to_dict(self) -> dict:
        """Plain data to rebuild the model: `YoungCA(**ca.to_dict())`."""
        return {"species": [list(s) for s in self.species], "neighbourhood": self.neighbourhood,
                "include_self": self.include_self, "denominator": int(self.denominator), "method": self.method}

    def _thresholds(self) -> tuple:
        """((T_act, T_inh), ...) per species: the radii as integer distance thresholds."""
        ra, ri = np.asarray(self.r_act), np.asarray(self.r_inh)
        return tuple((int(threshold(a, self.neighbourhood)), int(threshold(b, self.neighbourhood)))
                     for a, b in zip(ra, ri))

    def neighbour_counts(self, dim: int) -> np.ndarray:
        """Cells in each species' activator disc and inhibitor ring in `dim` dimensions,
        shape (K, 2) (the self cell counted in the disc only with include_self)."""
        out = []
        for t_act, t_inh in self._thresholds():
            n_act = ball_size(t_act, dim, self.neighbourhood) - (0 if self.include_self else 1)
            out.append((n_act, ball_size(t_inh, dim, self.neighbourhood) - ball_size(t_act, dim, self.neighbourhood)))
        return np.array(out, dtype=np.int64)

    def _integer_weights(self):
        den = self.denominator.astype(self.w_act.dtype)
        a = jnp.round(self.w_act * den).astype(jnp.int32)
        b = jnp.round(self.w_inh * den).astype(jnp.int32)
        return a, b

    def _host_integer_weights(self) -> tuple[np.ndarray, np.ndarray]:
        """`_integer_weights` of a concrete model in NumPy (also while a jit traces a
        function that closes over the model, where jnp operations would give tracers)."""
        den = int(self.denominator)
        return tuple(np.round(np.asarray(w, np.float64) * den).astype(np.int64) for w in (self.w_act, self.w_inh))

    # ---- planning (`_choice`; plans and spectra of concrete models cached, `_caches`) ----
    def _plan(self, shape) -> YoungPlan:
        shape, backend = tuple(shape), jax.default_backend()
        frozen = freeze(self)
        return make_plan(self, shape, backend) if frozen is None else cached_plan(frozen, shape, backend)

    def _precomputed(self, plan, shape):
        size = (1 if plan.combined else 2) * self.n_species * math.prod(shape[:-1]) * (shape[-1] // 2 + 1)
        if plan.method == "direct" or size > SPECTRA_MAX_SIZE:  # large: computing them per run costs little
            return None
        frozen = freeze(self)
        return None if frozen is None else cached_spectra(frozen, plan, tuple(shape), jax.default_backend())

    # ---- counting -----------------------------------------------------------------------
    def _fields(self, cells, plan: YoungPlan, spectra, n: int) -> Array:
        """Exact integer fields W_j x denominator, shape (K, *carried lattice), from the
        carried form of the cells (`_codec`); `n` is the lattice's last side."""
        k = self.n_species
        a, b = self._integer_weights()
        if plan.method == "direct":
            return direct_fields(cells, n, plan.thresholds, a, b, self.neighbourhood, self.include_self,
                                 plan.count_dtype)
        ind = jnp.stack([(cells == j) for j in range(k)]).astype(jnp.float32)
        if plan.combined:
            return jnp.round(_convolve(ind, spectra, plan)).astype(jnp.int32)
        counts = fft_counts(ind, spectra)
        bc = (slice(None),) + (None,) * cells.ndim
        return a[bc] * counts[:k] + b[bc] * counts[k:]

    def _spectra(self, plan: YoungPlan, shape):
        if plan.method == "direct":
            return None
        act, ring = neighbourhood_kernels(self.r_act, self.r_inh, self.neighbourhood, self.include_self, shape)
        if plan.combined:
            a, b = self._integer_weights()
            bc = (slice(None),) + (None,) * len(shape)
            kernel = a[bc].astype(act.dtype) * act + b[bc].astype(act.dtype) * ring
        else:
            kernel = jnp.concatenate([act, ring])
        if plan.method == "matmul":
            return matmul_spectra(kernel, plan.extent)
        return fft_spectra(kernel)

    def _binary(self, plan) -> bool:
        """One species with one weighted kernel: the loop carries the float indicator of
        species 0 straight into the transform (no conversions in the loop)."""
        return plan.method in ("fft", "matmul") and plan.combined and self.n_species == 1

    def _codec(self, plan, shape, dtype) -> Codec:
        if plan.width > shape[-1]:  # direct counting: the lattice widened periodically
            return Codec(lambda c: widen(c, plan.width), lambda c: c[..., :shape[-1]].astype(dtype))
        if not self._binary(plan):
            return identity_codec(dtype)
        return Codec(lambda c: (c == 0).astype(jnp.float32),
                     lambda x: jnp.where(x > 0.5, 0, 1).astype(dtype))

    def _stepper(self, plan, shape, pre=None):
        spectra = self._spectra(plan, shape) if pre is None else pre
        k = self.n_species
        if self._binary(plan):
            def binary_step(ind):
                # W x denominator is an integer and the transform error is < 0.1 (plan):
                # W > 0 <=> w > 1/2 and W < 0 <=> w < -1/2, exactly
                w = _convolve(ind[None], spectra, plan)[0]
                return jnp.where(w > 0.5, 1.0, jnp.where(w < -0.5, 0.0, ind)).astype(ind.dtype)

            return binary_step

        def step(cells):
            w = self._fields(cells, plan, spectra, shape[-1])
            if plan.keys:
                # one packed key per species, W_j (K + 1) + K - j, and their maximum: the
                # largest field, the lowest species on a tie (as argmax). Made from the
                # stacked fields, XLA:CPU computes the direct sums once, in the stacking op;
                # argmax, or a best/winner chain over the species' fields, fused the sums
                # into the update once per use (several times the step; bench_automata.md)
                tags = (k - jnp.arange(k, dtype=w.dtype)).reshape((k,) + (1,) * cells.ndim)
                keys = w * (k + 1) + tags
                key = functools.reduce(jnp.maximum, [keys[j] for j in range(k)])
                best = jnp.floor_divide(key, k + 1)
                winner = (k - (key - best * (k + 1))).astype(cells.dtype)
            else:
                best, winner = w[0], jnp.zeros((), cells.dtype)
                for j in range(1, k):
                    winner = jnp.where(w[j] > best, jnp.asarray(j, cells.dtype), winner)
                    best = jnp.maximum(best, w[j])
            undiff = jnp.asarray(k, cells.dtype)
            return jnp.where(best > 0, winner, jnp.where(best < 0, undiff, cells))

        return step

    def fields(self, cells) -> Array:
        """The net fields W_j (K, *lattice) as exact multiples of 1/denominator (float)."""
        cells = call(self, "_check_cells", cells)
        plan = call(self, "_plan", cells.shape)
        w = _jit_fields(self, cells, call(self, "_precomputed", plan, cells.shape), plan=plan)
        return w.astype(jnp.result_type(float)) / self.denominator.astype(jnp.result_type(float))

    # ---- differentiable relaxation (`_soft`) -------------------------------------------
    def soft_step(self, probs, temperature, *, edge=None) -> Array:
        """A differentiable relaxation of `step` on state probabilities (K + 1, *lattice).

        The fields W_j are computed from the probabilities of species j; the hard argmax
        over (W_0, ..., W_{K-1}, 0) becomes softmax(. / temperature) and the keep-on-tie
        rule a gate g = 1 - exp(-(max_j W_j / temperature)^2) between that softmax and the
        current probabilities. As temperature -> 0 this is the hard step on one-hot input
        (except on ties between species, split evenly here); a tie at W = 0 keeps the state
        at any temperature, because neighbour counts within 1e-3 of an integer are taken
        as that integer (in value; their gradients are kept). `temperature` is in units of
        the weights; `edge` (lattice cells) smooths the disc boundaries with a sigmoid so
        that the radii get gradients too (None: hard discs).
        """
        return soft_step(self, probs, temperature, edge)

    def soft_run(self, probs, steps: int, temperature, *, edge=None) -> Array:
        """`steps` soft steps in a `lax.scan` (reverse-mode differentiable)."""
        return soft_run(self, probs, steps, temperature, edge)


def _convolve(ind: Array, spectra, plan: YoungPlan) -> Array:
    """Periodic convolution of each of ind (B, *lattice) with its combined kernel, by the
    plan's float method."""
    if plan.method == "fft":
        return fft_convolve(ind, spectra)
    return matmul_convolve(ind, spectra, plan.extent)


@functools.partial(jax.jit, static_argnames=("plan",))
def _jit_fields(ca, cells, pre, *, plan):
    n = cells.shape[-1]
    wide = widen(cells, max(plan.width, n))
    return ca._fields(wide, plan, ca._spectra(plan, cells.shape) if pre is None else pre, n)[..., :n]
