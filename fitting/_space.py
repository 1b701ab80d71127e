"""The space of fitted parameters: names, bounds, and reparameterisations.

Optimisers work in an unconstrained vector z. Each parameter maps from a unit coordinate
u = sigmoid(z) in (0, 1) to its bounds: geometrically for positive parameters that span
decades (ratio, scale, diffusion rates, growth rate), linearly otherwise. Positivity and
bounds therefore always hold. An upper limit fitted together with its lower limit
(`lower_b` and `upper_b`) is parameterised as lower + u (bound - lower), so lower <= upper
whatever z is.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
from scipy.special import expit

# name: (low, high, geometric?), grouped by the model that has the parameter
DEFAULT_BOUNDS = {
    # Turing
    "ratio": (2.0, 50.0, True), "scale": (0.2, 8.0, True),
    # Bard
    "alpha": (8.0, 20.0, False), "beta": (8.0, 20.0, False),
    "sp": (1e-3, 1.0, True), "da": (1e-3, 10.0, True), "db": (1e-3, 10.0, True),
    # Gray-Scott
    "feed": (0.005, 0.1, False), "kill": (0.03, 0.08, False),
    "du": (0.02, 1.0, True), "dv": (0.01, 0.5, True),
    # Reinforcement
    "threshold": (0.0, 10.0, False), "width": (0.5, 10.0, True), "diffusion": (0.05, 5.0, True),
    # limits of any two-species model, and the growth schedule
    "lower_a": (0.0, 5.0, False), "lower_b": (0.0, 6.0, False),
    "upper_a": (3.5, 12.0, False), "upper_b": (2.0, 20.0, False),
    "growth_rate": (0.1, 20.0, True),
}


LIMITS = ("lower_a", "lower_b", "upper_a", "upper_b")


def base_name(name: str) -> str:
    """A parameter's name without its model path (`b.`) or phase (`growth:`): `upper_a`."""
    return name.rpartition(".")[2].rpartition(":")[2]


def default_bounds(name: str):
    base = base_name(name)
    if base in DEFAULT_BOUNDS:
        return DEFAULT_BOUNDS[base]
    raise ValueError(f"no default bounds for parameter {name!r}; give bounds={{'{name}': (low, high)}}")


@dataclasses.dataclass(frozen=True)
class ParamSpace:
    """Bounds and transforms for an ordered list of parameter names."""

    names: tuple
    low: tuple
    high: tuple
    geometric: tuple
    paired: tuple  # index of the lower limit an upper limit is tied to, or -1

    @classmethod
    def build(cls, names, bounds=None) -> "ParamSpace":
        names = tuple(names)
        if not names:
            raise ValueError("fit needs at least one parameter name to fit")
        if len(set(names)) != len(names):
            raise ValueError(f"fit names repeat: {names}")
        bounds = dict(bounds or {})
        low, high, geo = [], [], []
        for n in names:
            if n in bounds:
                b = bounds[n]
                lo, hi = float(b[0]), float(b[1])
                g = bool(b[2]) if len(b) > 2 else default_bounds(n)[2] if _known(n) else False
            else:
                lo, hi, g = default_bounds(n)
            if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
                raise ValueError(f"bounds for {n!r} must be finite with low < high (got {(lo, hi)})")
            if g and lo <= 0:
                raise ValueError(f"bounds for {n!r} are geometric and need low > 0 (got {lo})")
            low.append(lo)
            high.append(hi)
            geo.append(g)
        paired = []
        for n in names:
            kind, _, who = n.rpartition(".")[-1].partition("_")
            prefix = n[: len(n) - len(n.rpartition(".")[-1])]
            partner = f"{prefix}lower_{who}"
            paired.append(names.index(partner) if kind == "upper" and partner in names else -1)
        return cls(names, tuple(low), tuple(high), tuple(geo), tuple(paired))

    @property
    def size(self) -> int:
        return len(self.names)

    @property
    def limits(self) -> list:
        """Indices of the fitted saturation limits (lower_a, upper_b, ... of any phase)."""
        return [i for i, n in enumerate(self.names) if base_name(n) in LIMITS]

    def from_unit(self, u):
        """Unit coordinates (..., d) in [0, 1] -> parameter values (..., d). NumPy in, NumPy
        out (a fit's bookkeeping between compiled programs: nothing is compiled); JAX in, JAX
        out (inside a compiled loss, differentiable)."""
        xp = np if isinstance(u, np.ndarray) else jnp
        u = xp.asarray(u)
        lo, hi = xp.asarray(self.low, u.dtype), xp.asarray(self.high, u.dtype)
        geo = xp.asarray(self.geometric)
        lin = lo + u * (hi - lo)
        log = xp.exp(xp.log(xp.where(geo, lo, 1.0)) + u * (xp.log(xp.where(geo, hi, 2.0))
                                                           - xp.log(xp.where(geo, lo, 1.0))))
        vals = xp.where(geo, log, lin)
        columns = [vals[..., i] for i in range(self.size)]
        for i, j in enumerate(self.paired):
            if j >= 0:  # upper tied above its lower limit
                columns[i] = columns[j] + u[..., i] * (hi[i] - columns[j])
        return xp.stack(columns, axis=-1).astype(u.dtype)

    def to_unit(self, values):
        """Inverse of `from_unit` (NumPy, for starting points and reports)."""
        v = np.asarray(values, np.float64)
        lo, hi = np.asarray(self.low), np.asarray(self.high)
        u = np.empty_like(v)
        for i in range(self.size):
            if self.paired[i] >= 0:
                j = self.paired[i]
                u[..., i] = (v[..., i] - v[..., j]) / np.maximum(hi[i] - v[..., j], 1e-12)
            elif self.geometric[i]:
                u[..., i] = np.log(v[..., i] / lo[i]) / np.log(hi[i] / lo[i])
            else:
                u[..., i] = (v[..., i] - lo[i]) / (hi[i] - lo[i])
        return np.clip(u, 1e-6, 1 - 1e-6)

    def from_free(self, z):
        """Unconstrained z (the optimisers' space) -> parameter values (NumPy in, NumPy out,
        as `from_unit`)."""
        if isinstance(z, np.ndarray):
            return self.from_unit(expit(z))
        return self.from_unit(jax.nn.sigmoid(z))

    def to_free(self, values):
        """Unconstrained coordinates (logit of the position within the bounds) of natural parameter values."""
        u = self.to_unit(values)
        return np.log(u) - np.log1p(-u)

    def as_dict(self, values) -> dict:
        """{name: value} for a vector of natural parameter values, in the order of `names`."""
        return {n: values[..., i] for i, n in enumerate(self.names)}

    def design(self, n: int, method: str = "lhs", seed: int = 0) -> np.ndarray:
        """A coarse design of n points in unit coordinates: Latin hypercube or a grid."""
        rng = np.random.default_rng(seed)
        d = self.size
        if method == "lhs":
            cells = np.stack([rng.permutation(n) for _ in range(d)], axis=1)
            return (cells + rng.uniform(size=(n, d))) / n
        if method == "grid":
            per = max(2, int(round(n ** (1.0 / d))))
            axes = [(np.arange(per) + 0.5) / per] * d
            return np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, d)
        raise ValueError(f"unknown design {method!r}; allowed: 'lhs', 'grid'")


def _known(name: str) -> bool:
    try:
        default_bounds(name)
        return True
    except ValueError:
        return False
