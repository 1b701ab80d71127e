"""Tissue growth by random matrix expansion on a fixed-capacity lattice, and sources.

One expansion (leopard paper section 4): first a new row, where every column draws its
own dividing row r; that cell is duplicated and everything below it in the column moves
down by one; then a new column the same way, every row drawing its dividing column. All
species use the same dividing cells. The arrays keep their capacity shape throughout: the
active (rows, cols) grows inside them, so the whole experiment phase is one compiled
program with no Python loop over rows and no recompilation per size.

Dividing indices follow a law over the current active range [0, n):
"uniform"; "shuffle" (a random permutation of the n indices, reused cyclically, so every
index divides once per pass: the paper's shuffling); "normal" (clipped normal around the
middle, sd = spread * n); "triangular" (peak in the middle). `row_weights` / `col_weights`
multiply the law by a profile over the relative position (0 = first row, 1 = last), e.g.
the leopard's halved division probability in the middle rows.

The control experiment of section 8.2 (`method="nearest" | "bilinear" | "bicubic"`)
grows by image interpolation to (rows + 1, cols + 1) instead of cell division.
"""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.scipy.special
import jax.numpy as jnp
import numpy as np
from jax import Array

from ._checks import as_float_array, check_choice, check_finite, check_range, is_concrete

DISTRIBUTIONS = ("uniform", "shuffle", "normal", "triangular")
METHODS = ("division", "nearest", "bilinear", "bicubic")


class Growth(eqx.Module):
    """A growth schedule: `rate` expansions per unit of simulated time.

    An expansion happens every round(1 / (rate * dt)) steps of the phase, at the end of the
    first step of each period (phase steps 1, 1 + p, 1 + 2p, ...), after that step's
    reaction, diffusion and clamp; so N steps give ceil(N / p) expansions and the last one
    has p - 1 steps of reaction-diffusion after it to absorb its division noise. Each
    expansion adds one row and one column to the active lattice (two of each on a
    `HexLattice`, whose layout needs every dividing cell copied twice: see `expand`).

    Args:
        rate: expansions per unit time (time = steps x dt); 0 disables growth.
        distribution: law of the dividing indices (see module docstring).
        row_weights / col_weights: optional profiles (1D arrays) over relative position
            multiplying the law's mass of each index; resampled to the current size by
            nearest neighbour (all-ones weights leave the law as it is).
        spread: sd of the clipped normal as a fraction of the current size.
        method: "division" (random matrix expansion) or an interpolation control:
            "nearest", "bilinear", "bicubic".
    """

    rate: Array
    row_weights: Array | None
    col_weights: Array | None
    distribution: str = eqx.field(static=True)
    spread: float = eqx.field(static=True)
    method: str = eqx.field(static=True)

    def __init__(self, rate, distribution="uniform", row_weights=None, col_weights=None, spread=1.0 / 6.0,
                 method="division"):
        self.rate = as_float_array(rate, "Growth.rate")
        check_choice(distribution, "growth distribution", DISTRIBUTIONS)
        check_choice(method, "growth method", METHODS)
        self.distribution = distribution
        self.method = method
        try:
            self.spread = float(spread)
        except (TypeError, ValueError) as err:
            raise ValueError(f"Growth.spread must be a number, a fraction of the size (got {spread!r})") from err
        self.row_weights = None if row_weights is None else _weights(row_weights, "Growth.row_weights")
        self.col_weights = None if col_weights is None else _weights(col_weights, "Growth.col_weights")

    def __check_init__(self):
        check_finite(self.rate, "Growth.rate")
        check_range(self.rate, "Growth.rate (expansions per unit time)", low=0.0)
        if not (self.spread > 0 and math.isfinite(self.spread)):
            raise ValueError(f"Growth.spread (sd as a fraction of the size) must lie in (0, +inf) (got {self.spread})")
        if self.distribution == "shuffle" and (self.row_weights is not None or self.col_weights is not None):
            raise ValueError("Growth: row_weights/col_weights cannot be combined with distribution='shuffle'")

    # ---- schedule ------------------------------------------------------------------
    def period(self, dt):
        """Steps between expansions, round(1 / (rate dt)) (0 when the rate is 0)."""
        rate_dt = self.rate * dt
        return jnp.where(rate_dt > 0, jnp.maximum(jnp.round(1.0 / jnp.where(rate_dt > 0, rate_dt, 1.0)), 1), 0).astype(
            jnp.int32)

    def period_steps(self, dt) -> int:
        """`period` for concrete values, computed in NumPy (usable while tracing)."""
        dtype = np.asarray(self.rate).dtype  # same precision as the traced `period`
        rate_dt = np.asarray(self.rate, dtype) * np.asarray(dt, dtype)
        return max(int(np.round(dtype.type(1.0) / rate_dt)), 1) if rate_dt > 0 else 0

    def expansions(self, steps: int, dt, done: int = 0) -> int:
        """Number of expansions in phase steps done+1 .. done+steps (concrete values)."""
        period = self.period_steps(dt)
        if period == 0:
            return 0
        return -(-(done + steps) // period) - (-(-done // period))

    def due(self, state, steps: int, dt, origin=None) -> int | None:
        """Expansions in the next `steps` steps of a phase that started at step `origin`
        (None: this run starts the phase), None when the values are traced."""
        if not is_concrete(self.rate, dt, state.step, origin):
            return None
        return self.expansions(steps, dt, steps_done(state, origin))

    def check_capacity(self, state, steps: int, dt, origin=None, copies: int = 1) -> None:
        """Raise before the run if the state cannot hold all the expansions it will get
        (`copies`: rows and columns one expansion adds, see `expand`)."""
        n = self.due(state, steps, dt, origin)
        if n is None or not is_concrete(state.size):
            return
        h, w = state.shape
        cap = state.capacity
        n = n * copies
        if h + n > cap[0] or w + n > cap[1]:
            raise ValueError(
                f"growth would take the lattice from {h}x{w} to {h + n}x{w + n} in {steps} steps "
                f"({n} expansions, one every {self.period_steps(dt)} steps), beyond the capacity "
                f"{cap[0]}x{cap[1]}; give the state a larger capacity (state.with_capacity, or in an experiment "
                "Initial(capacity=...) / Phase(capacity=...))"
            )

    def is_due(self, k, dt):
        """Whether phase step `k` (1-based, may be traced) opens a period: an expansion follows it."""
        period = self.period(dt)
        return (period > 0) & ((k - 1) % jnp.maximum(period, 1) == 0)

    # ---- one expansion -----------------------------------------------------------------
    def expand(self, x, size, key, copies: int = 1):
        """One expansion of the active region: new rows, then new columns.

        `copies` (static) is how many times each dividing cell is duplicated: 1 on the
        square lattice (a new row and a new column), 2 on the hexagonal lattice, whose odd
        rows sit half a cell to the right: there the dividing cell of each column fills
        three rows and the cells below it move down two rows, keeping their row parity and
        so their place across the lattice; along a row the dividing cell fills three
        columns and the cells after it move two whole cells right. One expansion then adds
        two rows and two columns, from the same draws as a square lattice's one of each.
        """
        if self.method != "division":
            if copies != 1:
                raise ValueError(f"growth method {self.method!r} resamples a square lattice; the hexagonal lattice "
                                 "grows by division only (method='division')")
            return _interpolate(x, size, self.method)
        kr, kc = jax.random.split(key)
        h, w = size[0], size[1]
        rows = self.draw(kr, h, x.shape[-1], x.shape[-2], self.row_weights)  # one dividing row per column
        for _ in range(copies):  # each copy moves the cells after the dividing one by one more
            x = _insert(x, rows, axis=-2)
        cols = self.draw(kc, w, x.shape[-2], x.shape[-1], self.col_weights)  # one dividing column per row
        for _ in range(copies):
            x = _insert(x, cols, axis=-1)
        return x, size + copies

    def birth_times(self, shape, expansions: int, key):
        """Which expansion created each cell: the paper's Fig. 3 as an array.

        Starts from a `shape` lattice of original cells (0) and applies `expansions`
        expansions with this growth's law and weights (its own draws from `key`, not
        those a `simulate` run with the same key makes);
        the cell a division inserts (the lower / right copy) is labelled with the number of
        its expansion (1, 2, ...). Returns an int32 JAX array of shape (rows + expansions,
        cols + expansions). Expansion k adds cols + k - 1 cells (the new row) and
        rows + k cells (the new column). Division growth only.
        """
        if self.method != "division":
            raise ValueError(f"birth_times needs growth method 'division' (got {self.method!r})")
        check_shape = tuple(int(s) for s in shape)
        if len(check_shape) != 2 or min(check_shape) < 1 or int(expansions) < 0:
            raise ValueError(f"birth_times: shape must be two sizes >= 1 and expansions >= 0 "
                             f"(got {shape}, {expansions})")
        (h, w), n = check_shape, int(expansions)
        H, W = h + n, w + n
        ids = jnp.arange(H * W, dtype=jnp.int32).reshape(H, W)  # distinct labels to find the copies

        def one(carry, k):
            birth, size = carry
            kr, kc = jax.random.split(jax.random.fold_in(key, k))
            for axis, kk, weights in ((-2, kr, self.row_weights), (-1, kc, self.col_weights)):
                n_along = size[0] if axis == -2 else size[1]
                count, cap = (W, H) if axis == -2 else (H, W)
                x = _insert(jnp.stack([birth, ids]), self.draw(kk, n_along, count, cap, weights), axis)
                prev = jnp.roll(x[1], 1, axis=axis)
                copy = x[1] == prev
                copy = copy.at[0, :].set(False) if axis == -2 else copy.at[:, 0].set(False)
                birth = jnp.where(copy, k + 1, x[0])
                size = size.at[0 if axis == -2 else 1].add(1)
            return (birth, size), None

        start = jnp.zeros((H, W), jnp.int32)
        (birth, _), _ = jax.lax.scan(one, (start, jnp.array([h, w], jnp.int32)), jnp.arange(n, dtype=jnp.int32))
        return birth

    def draw(self, key, n, count: int, cap: int, weights=None):
        """`count` dividing indices in [0, n) following the law; n (maybe traced) <= cap."""
        n = jnp.asarray(n)
        if self.distribution == "shuffle":
            # a random permutation of 0..n-1 (random keys, the unused tail sorted last),
            # used cyclically: every index divides once per pass
            order = jnp.argsort(jnp.where(jnp.arange(cap) < n, jax.random.uniform(key, (cap,)), 2.0))
            return order[jnp.arange(count) % n].astype(jnp.int32)
        if weights is not None:
            return _draw_weighted(key, n, count, self.pmf_profile(weights), cap)
        nf = n.astype(jnp.float32)
        if self.distribution == "uniform":
            idx = jnp.floor(jax.random.uniform(key, (count,)) * nf)
        elif self.distribution == "triangular":
            u = jax.random.uniform(key, (count, 2))  # (count, 2): the first draws do not depend on count
            idx = jnp.floor((u[:, 0] + u[:, 1]) * 0.5 * nf)
        else:  # clipped normal
            z = jax.random.normal(key, (count,))
            idx = jnp.round((nf - 1) / 2 + z * self.spread * nf)
        return jnp.clip(idx, 0, nf - 1).astype(jnp.int32)

    def pmf_profile(self, weights):
        """The law's exact mass of each index times the weight profile: a function of
        (index i, current size n), unnormalised; all-ones weights give the law itself."""
        dist, spread = self.distribution, self.spread

        def profile(i, n):
            i = jnp.asarray(i, jnp.float32)
            nf = jnp.asarray(n, jnp.float32)
            if dist == "triangular":  # floor(n (u1 + u2) / 2): the triangular cdf over each cell
                cdf = lambda s: jnp.where(s < 0.5, 2.0 * s * s, 1.0 - 2.0 * (1.0 - s) ** 2)
                base = cdf(jnp.clip((i + 1.0) / nf, 0.0, 1.0)) - cdf(jnp.clip(i / nf, 0.0, 1.0))
            elif dist == "normal":  # rounded, clipped: the tails pile on the edge cells
                mu, sd = (nf - 1.0) / 2.0, spread * nf
                upper = jnp.where(i >= nf - 1.0, 1.0, jax.scipy.special.ndtr((i + 0.5 - mu) / sd))
                lower = jnp.where(i <= 0.0, 0.0, jax.scipy.special.ndtr((i - 0.5 - mu) / sd))
                base = upper - lower
            else:  # uniform, shuffle
                base = jnp.ones_like(i)
            k = weights.shape[0]
            idx = jnp.clip(jnp.floor((i + 0.5) / nf * k).astype(jnp.int32), 0, k - 1)
            return base * weights[idx]

        return profile

    def law(self, n: int, weights=None) -> np.ndarray:
        """The exact probability of each index 0..n-1, for tests and figures."""
        p = np.asarray(self.pmf_profile(jnp.ones(1) if weights is None else jnp.asarray(weights))(np.arange(n), n),
                       float)
        return p / p.sum()


def steps_done(state, origin) -> int:
    """Steps of its phase a concrete state has done (`origin`: the phase's first step;
    None: the state is at the phase's start)."""
    return 0 if origin is None else int(state.step) - int(origin)


def _draw_weighted(key, n, count: int, profile, cap: int):
    """`count` indices in [0, n) with probabilities proportional to `profile`, by inverting
    the cumulative distribution (one uniform number per index drawn)."""
    p = jnp.where(jnp.arange(cap) < n, profile(jnp.arange(cap), n), 0.0)
    cdf = jnp.cumsum(p)
    u = jax.random.uniform(key, (count,), cdf.dtype) * cdf[-1]
    idx = jnp.searchsorted(cdf, u, side="right")
    return jnp.clip(idx, 0, n - 1).astype(jnp.int32)


def _weights(values, name):
    arr = as_float_array(values, name)
    if arr.ndim != 1 or arr.shape[0] < 1:
        raise ValueError(f"{name} must be a 1D profile of weights (got shape {arr.shape})")
    check_finite(arr, name)
    check_range(arr, name, low=0.0)
    if is_concrete(arr) and not float(jnp.max(arr)) > 0:
        raise ValueError(f"{name} must have at least one positive weight")
    return arr


def _insert(x, idx, axis):
    """Duplicate, in every line across `axis`, the cell at `idx[line]`; later cells shift by one.

    Written as a select between the array and its copy shifted by one cell (no gather),
    which XLA fuses into a single pass.
    """
    if axis == -2:  # idx: the dividing row of each column
        shifted = jnp.concatenate([x[..., :1, :], x[..., :-1, :]], axis=-2)  # cell i <- cell i - 1
        after = jnp.arange(x.shape[-2])[:, None] > idx[None, :]
    else:  # idx: the dividing column of each row
        shifted = jnp.concatenate([x[..., :, :1], x[..., :, :-1]], axis=-1)
        after = jnp.arange(x.shape[-1])[None, :] > idx[:, None]
    return jnp.where(after, shifted, x)


def _interpolate(x, size, method):
    """Resample the active (h, w) region to (h + 1, w + 1): the section 8.2 control."""
    h, w = size[0], size[1]
    x = _resample_axis(x, h, -2, method)
    x = _resample_axis(x, w, -1, method)
    return x, size + 1


def _resample_axis(x, n, axis, method):
    """Resample along `axis` from n to n + 1 samples (align-corners off, edge clamped)."""
    length = x.shape[axis]
    i = jnp.arange(length, dtype=x.dtype)
    nf = n.astype(x.dtype)
    pos = (i + 0.5) * nf / (nf + 1.0) - 0.5  # source coordinate of each new cell
    last = n - 1

    def take(k):
        k = jnp.clip(k, 0, last)
        shape = [1] * x.ndim
        shape[axis] = length
        return jnp.take_along_axis(x, jnp.broadcast_to(k.reshape(shape), x.shape), axis=axis)

    def along(v):
        shape = [1] * x.ndim
        shape[axis] = length
        return v.reshape(shape)

    if method == "nearest":
        out = take(jnp.round(pos).astype(jnp.int32))
    elif method == "bilinear":
        f = jnp.floor(pos)
        t = along(pos - f)
        k = f.astype(jnp.int32)
        out = (1 - t) * take(k) + t * take(k + 1)
    else:  # bicubic, Keys kernel with a = -0.5
        f = jnp.floor(pos)
        t = pos - f
        k = f.astype(jnp.int32)
        out = 0.0
        for off in (-1, 0, 1, 2):
            out = out + along(_keys_kernel(t - off)) * take(k + off)
    valid = along(i < nf + 1)
    return jnp.where(valid, out, 0.0)


def _keys_kernel(s, a=-0.5):
    s = jnp.abs(s)
    return jnp.where(s <= 1, (a + 2) * s**3 - (a + 3) * s**2 + 1,
                     jnp.where(s < 2, a * s**3 - 5 * a * s**2 + 8 * a * s - 4 * a, 0.0))


# ---- localised production ------------------------------------------------------------
REGIONS = ("all", "center-row", "top-row", "bottom-row", "center-col")


class Source(eqx.Module):
    """Localised production: each step add U[0, amplitude) of `species` on a region.

    region: "center-row" (the neural crest of the squirrel and leopard experiments, the
    middle row of the *active* lattice, so it follows growth), "top-row", "bottom-row",
    "center-col", "all", or a boolean/weight mask of the state's capacity shape.
    Production is added after the reaction-diffusion update and before the clamp.
    """

    amplitude: Array
    mask: Array | None
    species: str | int = eqx.field(static=True)
    region: str = eqx.field(static=True)
    index: int = eqx.field(static=True)

    def __init__(self, species, amplitude, region="center-row", *, index=-1):
        self.species = species
        self.amplitude = as_float_array(amplitude, "Source.amplitude")
        if isinstance(region, str):
            check_choice(region, "source region", REGIONS)
            self.region = region
            self.mask = None
        else:
            self.region = "mask"
            self.mask = as_float_array(region, "Source.region (mask)")
        self.index = int(index)

    def __check_init__(self):
        check_finite(self.amplitude, "Source.amplitude")
        check_range(self.amplitude, "Source.amplitude", low=0.0)
        if self.mask is not None:
            check_finite(self.mask, "Source.region (mask)")
            check_range(self.mask, "Source.region (mask weights)", low=0.0)

    def check(self, state):
        """Raise a ValueError if the species or the mask does not fit `state` (before a run)."""
        idx = state.index(self.species)
        if self.mask is not None and self.mask.shape != tuple(state.capacity):
            raise ValueError(f"Source mask has shape {self.mask.shape}; it must match the capacity {state.capacity}")
        return Source(self.species, self.amplitude, self.region if self.mask is None else self.mask, index=idx)

    def production(self, size, key, like):
        """This step's production: U[0, amplitude) on the region, zero elsewhere (shaped like `like`)."""
        rows, cols = like.shape[-2:]
        dtype = like.dtype
        r = jnp.arange(rows)[:, None]
        c = jnp.arange(cols)[None, :]
        if self.region in ("mask", "all"):
            # one key per row, so that a cell's number does not depend on the width of the
            # block a run computes on (eager runs use blocks of the capacity, jit the whole)
            keys = jax.vmap(lambda i: jax.random.fold_in(key, i))(jnp.arange(rows))
            noise = jax.vmap(lambda k: jax.random.uniform(k, (cols,), dtype))(keys) * self.amplitude
            if self.region == "mask":
                return noise * self.mask[:rows, :cols]
            return noise * ((r < size[0]) & (c < size[1]))
        # a single row or column: draw only the numbers it needs
        if self.region in ("center-row", "top-row", "bottom-row"):
            at = {"center-row": size[0] // 2, "top-row": 0, "bottom-row": size[0] - 1}[self.region]
            line = jax.random.uniform(key, (1, cols), dtype) * self.amplitude
            return jnp.where((r == at) & (c < size[1]), line, 0.0)
        line = jax.random.uniform(key, (rows, 1), dtype) * self.amplitude
        return jnp.where((c == size[1] // 2) & (r < size[0]), line, 0.0)
