"""From fitted parameters to a simulated field: the forward model of a fit.

`Simulator` wraps a model (one static phase) or a multi-phase `Experiment` (growth, sources,
species added between phases). It is a pure function of (parameters, key), so fits can
vmap it over seeds and design points and differentiate it.

Time step: for a model the step adapts to the parameters, dt = min(safety x the explicit-
Euler limit, dt_cap), so every point of the parameter space is stable with the same number
of steps (the simulated time is steps x dt). Experiments keep their phases' dt (their growth
schedules are in steps), so their bounds must keep every phase stable.

Gradients: only the last `window` steps are differentiated; the state before them is held
constant (truncated backpropagation through time). Over long horizons the exact gradient of
a pattern-forming run is dominated by where individual spots happen to sit, not by the
texture, and grows without bound; differentiating the final relaxation towards the settled
pattern gives the informative part (see docs in `fitting/__init__.py`).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

import morphojax as mj


# the diffusion rates `diffusion_scale` multiplies (Turing's diffusion is its `scale`)
DIFFUSION_NAMES = ("da", "db", "du", "dv", "diffusion")


def _apply(model: mj.AbstractModel, params: dict) -> mj.AbstractModel:
    """Set the parameters this model has (composites: in every part that has them).

    `diffusion_scale` multiplies every diffusion rate of the template (those in
    DIFFUSION_NAMES not set explicitly): wavelengths scale as its square root."""
    if isinstance(model, mj.Composite):
        parts = tuple(_apply(p, params) for p in model.parts)
        return mj.Composite(parts, species=model.species)
    own = model.parameters()
    known = {k: v for k, v in params.items() if k in own}
    if "diffusion_scale" in params:
        for k in DIFFUSION_NAMES:
            if k in own and k not in known:
                known[k] = own[k] * params["diffusion_scale"]
    return model.replace(**known) if known else model


def _has(model: mj.AbstractModel, name: str) -> bool:
    if isinstance(model, mj.Composite):
        return any(_has(p, name) for p in model.parts)
    if name == "diffusion_scale":
        return any(k in model.parameters() for k in DIFFUSION_NAMES)
    return name in model.parameters()


# Young's automaton through its soft relaxation (`YoungCA.soft_run`): weights are compared
# over this denominator, the temperature is in units of the weights, the disc edges are
# smoothed over this many cells (so the radii get gradients)
YOUNG_DENOMINATOR, YOUNG_TEMPERATURE, YOUNG_EDGE = 100, 0.05, 0.5
YOUNG_PARAMETERS = ("r_act", "r_inh", "w_act", "w_inh")


def _young(template: mj.YoungCA, params: dict) -> mj.YoungCA:
    """One-species YoungCA with `params` (r_act, r_inh, w_act, w_inh) set. The weights snap
    to multiples of 1 / YOUNG_DENOMINATOR in value (their gradients pass straight through)
    and r_inh is at least r_act (an empty ring otherwise), so every point is a valid model."""
    values = {n: params.get(n, getattr(template, n)[0]) for n in YOUNG_PARAMETERS}
    r_act = jnp.asarray(values["r_act"], jnp.float32)
    r_inh = jnp.maximum(jnp.asarray(values["r_inh"], jnp.float32), r_act)

    def snap(w):
        w = jnp.asarray(w, jnp.float32)
        return w + jax.lax.stop_gradient(jnp.round(w * YOUNG_DENOMINATOR) / YOUNG_DENOMINATOR - w)

    row = jnp.stack([r_act, r_inh, snap(values["w_act"]), snap(values["w_inh"])])
    return mj.YoungCA(row[None], template.neighbourhood, template.include_self, denominator=YOUNG_DENOMINATOR)


class Simulator(eqx.Module):
    """How a dict of parameters becomes one simulated 2D field.

    Args:
        template: a model (e.g. `Turing(...)`) or an `Experiment`; fitted and fixed parameters
            replace its values by name. For experiments a name applies to every phase whose
            model has it; "PHASE:name" restricts it to the phase called PHASE; "growth_rate"
            sets the rate of every growing phase (or "PHASE:growth_rate").
        shape: lattice (rows, cols) for a model template.
        steps, window: steps per run and how many of the last are differentiated.
        species: the species compared with the target (default: the experiment's `show`, or
            the model's last species, B for Turing).
        boundary, stencil: for a model template.
        anisotropic: for a model template, the species whose diffusion follows a polarity
            (`mj.Lattice(anisotropic=...)`, thesis eq. 4.8); the polarity is the parameter
            `angle` (radians from the +x axis toward increasing row; orientations are
            modulo pi), uniform over the lattice, fittable like the model's parameters.
        safety, dt_cap, dt: adaptive time step for a model template (dt fixes it instead).
        fixed: parameters set before the fitted ones.
        solver, stride: how a model template is stepped: `solver` (default `mj.Euler()`)
            takes one step of `stride` times the Euler time step for every `stride` of
            `steps`, so the simulated time and the differentiated stretch of time are
            Euler's (`steps` and `window` must be multiples of `stride`). A family declares
            the solver whose statistics match Euler's within the seed-to-seed spread
            (`fitting.FAMILIES`, measured by `benchmarks/fit_solvers.py`).
    """

    template: Any  # a pytree: its parameters are traced, so fits reuse compiled programs
    shape: tuple = eqx.field(static=True, default=(64, 64))
    steps: int = eqx.field(static=True, default=8000)
    window: int = eqx.field(static=True, default=1000)
    species: str | None = eqx.field(static=True, default=None)
    boundary: str = eqx.field(static=True, default="wrap")
    stencil: str = eqx.field(static=True, default="nine-point")
    anisotropic: tuple = eqx.field(static=True, default=())
    safety: float = eqx.field(static=True, default=0.8)
    dt_cap: float = eqx.field(static=True, default=0.01)
    dt: float | None = eqx.field(static=True, default=None)
    fixed: tuple = eqx.field(static=True, default=())
    compare: tuple | None = eqx.field(static=True, default=None)
    solver: Any = eqx.field(static=True, default=None)  # None: forward Euler
    stride: int = eqx.field(static=True, default=1)

    def __post_init__(self):
        # the compared lattice of an experiment, fixed while the parameters are concrete
        # (inside compiled fits the growth rates are traced)
        if self.compare is None and isinstance(self.template, mj.Experiment):
            self.compare = self.final_shape()

    def __check_init__(self):
        if not isinstance(self.template, (mj.AbstractModel, mj.Experiment, mj.YoungCA)):
            raise ValueError("Simulator.template must be a model, an Experiment or a one-species YoungCA "
                             f"(got {type(self.template).__name__})")
        if isinstance(self.template, mj.YoungCA) and self.template.n_species != 1:
            raise ValueError(f"Simulator.template: a YoungCA must have one species (got {self.template.n_species})")
        if not isinstance(self.template, mj.Experiment) and (self.steps < 1 or not 0 <= self.window <= self.steps):
            raise ValueError(f"need steps >= 1 and 0 <= window <= steps (got steps={self.steps}, window={self.window})")
        if int(self.stride) < 1 or self.steps % self.stride or self.window % self.stride:
            raise ValueError(f"Simulator.stride must be an integer >= 1 dividing steps and window "
                             f"(got stride={self.stride}, steps={self.steps}, window={self.window})")
        if (self.solver is not None or self.stride != 1) and not isinstance(self.template, mj.AbstractModel):
            raise ValueError("Simulator.solver and stride step a model template; experiments and automata "
                             "keep their own steps")

    # ---- parameters -------------------------------------------------------------------
    def parameter_names(self) -> list[str]:
        """Names that can be fitted or fixed (for experiments: the union over phases, and growth_rate)."""
        if isinstance(self.template, mj.YoungCA):
            return list(YOUNG_PARAMETERS)
        if isinstance(self.template, mj.AbstractModel):
            return list(self.template.parameters()) + (
                ["diffusion_scale"] if _has(self.template, "diffusion_scale") else []) + (
                ["angle"] if self.anisotropic else [])
        names = []
        for ph in self.template.phases:
            for n in ph.model.parameters():
                base = n.split(".", 1)[-1] if isinstance(ph.model, mj.Composite) else n
                if base not in names:
                    names.append(base)
        if any(_has(ph.model, "diffusion_scale") for ph in self.template.phases):
            names.append("diffusion_scale")
        return names + (["growth_rate"] if any(ph.growth is not None for ph in self.template.phases) else [])

    def check_names(self, names) -> None:
        """Raise a ValueError for a name the template does not have (or an unknown PHASE: prefix)."""
        known = self.parameter_names()
        phases = {ph.name for ph in self.template.phases} if isinstance(self.template, mj.Experiment) else set()
        for n in names:
            ph, _, base = n.rpartition(":")
            if base not in known or (ph and ph not in phases):
                raise ValueError(f"cannot fit {n!r}: the model's parameters are {', '.join(known)}"
                                 + (f"; phases: {', '.join(sorted(phases))}" if phases else ""))

    def build(self, params: dict):
        """The model or experiment with `params` (and `fixed`) applied."""
        params = {**dict(self.fixed), **params}
        if isinstance(self.template, mj.YoungCA):
            return _young(self.template, params)
        if isinstance(self.template, mj.AbstractModel):
            return _apply(self.template, params)
        phases = []
        for ph in self.template.phases:
            mine = {}
            for k, v in params.items():
                target, _, base = k.rpartition(":")
                if not target or target == ph.name:
                    mine[base] = v
            growth = ph.growth
            if growth is not None and "growth_rate" in mine:
                growth = eqx.tree_at(lambda g: g.rate, growth, jnp.asarray(mine["growth_rate"], growth.rate.dtype))
            model_params = {k: v for k, v in mine.items() if k != "growth_rate" and _has(ph.model, k)}
            phases.append(mj.Phase(**{**ph.__dict__, "model": _apply(ph.model, model_params), "growth": growth}))
        return dataclasses.replace(self.template, phases=tuple(phases))

    # ---- forward ----------------------------------------------------------------------
    def time_step(self, model):
        """dt for `model`: min(safety x the explicit-Euler limit of its largest diffusion, dt_cap), or the fixed dt."""
        if self.dt is not None:
            return jnp.asarray(self.dt)
        limit = mj.Lattice(self.stencil).max_stable_dt(jnp.max(model.diffusion()))  # traced: a JAX array
        return jnp.minimum(self.safety * limit, self.dt_cap)

    def _species(self, names) -> int:
        if self.species is not None:
            return names.index(self.species)
        if isinstance(self.template, mj.Experiment) and self.template.show in names:
            return names.index(self.template.show)
        return len(names) - 1

    def run(self, params: dict, key):
        """One simulated field (rows, cols) for `params` and `key`; NaN never comes out."""
        if isinstance(self.template, mj.YoungCA):
            # Young's start (a cell differentiated with probability YOUNG_P), relaxed softly;
            # the field is the differentiated probability. The first steps - window steps
            # are not differentiated.
            ca = self.build(params)
            cells = mj.random_cells(jax.random.fold_in(key, 0), self.shape, k=1, p=mj.YOUNG_P)
            probs = jax.nn.one_hot(cells, 2, axis=0, dtype=jnp.float32)
            head = self.steps - self.window
            if head > 0:
                probs = jax.lax.stop_gradient(ca.soft_run(probs, head, YOUNG_TEMPERATURE, edge=YOUNG_EDGE))
            field = ca.soft_run(probs, self.window, YOUNG_TEMPERATURE, edge=YOUNG_EDGE)[0]
            return jnp.where(jnp.isfinite(field), field, 0.0)
        if isinstance(self.template, mj.AbstractModel):
            model = self.build(params)
            state = _start(self.template, model, jax.random.fold_in(key, 0), self.shape)
            dt = self.time_step(model) * self.stride
            opts = dict(domain=self.domain(params), check_dt=False, throw=False, solver=self.solver)
            head = (self.steps - self.window) // self.stride
            if head > 0:
                state = jax.lax.stop_gradient(mj.simulate(model, state, steps=head, dt=dt, **opts))
            state = mj.simulate(model, state, steps=self.window // self.stride, dt=dt, checkpoint=True, **opts)
            field = state.fields[self._species(state.names)]
        else:
            exp = self.build(params)
            result = mj.run_experiment(exp, key=key, grad_window=self.window, throw=False)
            state = result.state
            rows, cols = self.final_shape()
            field = state.fields[self._species(state.names), :rows, :cols]
        return jnp.where(jnp.isfinite(field), field, 0.0)

    def domain(self, params: dict) -> mj.Lattice:
        """The lattice of a model template's run: anisotropic along `angle` when the
        simulator has anisotropic species (a traced leaf, so the angle is differentiable)."""
        if not self.anisotropic:
            return mj.Lattice(self.stencil, self.boundary)
        angle = {**dict(self.fixed), **params}.get("angle", 0.0)
        return mj.Lattice(self.stencil, self.boundary, anisotropic=self.anisotropic, polarity=angle)

    def final_shape(self, params: dict | None = None) -> tuple:
        """The lattice the compared field lives on (concrete, from the growth schedules).

        Experiments: the final lattice of the template (`compare`, fixed when the simulator
        is made), or with `params` (concrete values) the final lattice they give. When growth
        rates are fitted, `fit` sets `compare` to the lattice of the lowest rates, so every
        point compares the same top-left window of its grown lattice.
        """
        if not isinstance(self.template, mj.Experiment):
            return tuple(self.shape)
        if params is None and self.compare is not None:
            return tuple(self.compare)
        return self._sizes(params)[-1][0]

    def _sizes(self, params) -> list:
        """(lattice, capacity) after each phase of the experiment, for concrete values."""
        exp = self.template if params is None else self.build(params)
        (rows, cols), cap = exp.initial.shape, exp.initial.capacity or exp.initial.shape
        out = []
        for ph in exp.phases:
            cap = ph.capacity or cap
            if ph.growth is not None:
                n = ph.growth.expansions(ph.steps, ph.dt)
                rows, cols = rows + n, cols + n
            out.append(((int(rows), int(cols)), tuple(cap)))
        return out

    def check_capacity(self, params: dict) -> None:
        """Raise if the growth `params` give (concrete values) needs more than the capacity."""
        if not isinstance(self.template, mj.Experiment):
            return
        for ph, ((rows, cols), cap) in zip(self.template.phases, self._sizes(params)):
            if rows > cap[0] or cols > cap[1]:
                raise ValueError(
                    f"with {params} phase {ph.name!r} grows the lattice to {rows}x{cols}, beyond its capacity "
                    f"{cap[0]}x{cap[1]}: lower the growth_rate bounds or give the experiment more capacity")

    def describe(self) -> dict:
        """JSON-ready description of the simulator (template, lattice, steps, window, time step)."""
        tmpl = (mj.model_to_dict(self.template) if isinstance(self.template, mj.AbstractModel)
                else self.template.to_dict())  # an Experiment's or a YoungCA's own
        return mj.to_jsonable({"template": tmpl, "shape": list(self.final_shape()), "steps": self.steps,
                               "window": self.window, "species": self.species, "boundary": self.boundary,
                               "stencil": self.stencil, "anisotropic": list(self.anisotropic), "safety": self.safety,
                               "dt_cap": self.dt_cap, "dt": self.dt, "fixed": dict(self.fixed),
                               "solver": mj.solvers.solver_to_dict(self.solver), "stride": self.stride})


def _start(template, model, key, shape):
    """The model's customary random start; reinforcement's, uniform in [t - w, t + w), from the
    built (possibly traced) threshold t and width w."""
    if isinstance(template, mj.Reinforcement):
        u = mj.random_state(key, shape, (0.0, 1.0), names=("c",)).fields[0]
        t, w = model.threshold, model.width
        return mj.State.from_arrays([t - w + 2.0 * w * u], names=("c",))
    if isinstance(template, mj.GrayScott):
        # Pearson's perturbation (u, v) = (0.5, 0.25) in scattered 4x4 blocks (about one per
        # hundred cells) instead of one central square, so the pattern fills any lattice
        # in the same simulated time and seeds differ in more than noise
        rows, cols = shape
        k1, k2 = jax.random.split(key)
        blocks = jax.random.uniform(k1, ((rows + 3) // 4, (cols + 3) // 4)) < 0.15
        mask = jnp.kron(blocks, jnp.ones((4, 4)))[:rows, :cols]
        noise = mj.random_state(k2, shape, (-0.02, 0.02), (-0.02, 0.02)).fields
        u = jnp.clip(jnp.where(mask, 0.5, 1.0) + noise[0], 0.0, 1.0)
        v = jnp.clip(jnp.where(mask, 0.25, 0.0) + noise[1], 0.0, 1.0)
        return mj.State.from_arrays([u, v], names=("u", "v"))
    return mj.initial_state(template, key, shape)


def fixed_tuple(fixed: dict | None) -> tuple:
    return tuple(sorted((str(k), float(np.asarray(v))) for k, v in (fixed or {}).items()))
