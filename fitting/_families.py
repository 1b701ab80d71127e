"""The model families a fit searches, declared in one place.

A family says how to build its template on a lattice, which parameters it has, their
default bounds, which it fits by default, the run it needs (steps, differentiated window,
time-step cap) and how its length scale moves: `length` is the parameter that scales the
pattern's wavelength as wavelength ~ length ** `length_power`, so the global design can move
each point to the target's wavelength (`fitting._fit`).

Length scales. In a reaction-diffusion model every wavelength scales as sqrt(D) when all
diffusion rates D are multiplied by one factor (the dimensionless equations are unchanged
with x -> x sqrt(factor)). Turing's `scale` multiplies its diffusion rates (leopard paper
eqs. 3-4), so wavelength ~ scale ** 0.5; Bard and Gray-Scott have no such parameter, so
their families fit `diffusion_scale`, a common factor on their template's diffusion rates
(`fitting.Simulator`). The three-phase leopard experiment moves its wavelength through the
definition phase's `scale`, which sets the spot spacing that later phases inherit. Young's
automaton has no such parameter (its radii are the length scale, and moving one alone
changes the pattern's kind), so its design searches the radii directly; its runs cost about
a millisecond, so that is cheap.

Lower bounds keep every family's pattern above the lattice scale. Photos are resampled to
10 cells per wavelength, so a pattern whose features are a cell or two wide is never the
answer, but its fine texture can match a photo's fur: with lower bounds of 0.1 the cheetah's
auto fit picked Gray-Scott rings locked to the lattice's squares. Measured on 64x64 lattices
(dominant wavelength, cells): Gray-Scott 5.3 at diffusion_scale 0.1 (square rings), 8.6 at
0.25; Bard 2.2 at 0.05 and 4.5 at 0.3 (lattice noise), 6.8 at 0.5; reinforcement lattice
noise at diffusion 0.2 (4.5), blotches of 27 at 0.5 after its 4,000 steps, so its wavelength
moves about as diffusion ** 2 there (`length_power`), not as the square root.

Oriented coats (zebra, tiger): `anisotropic-turing` is Turing's model with the inhibitor B
diffusing along a polarity (thesis eq. 4.8, `mj.Lattice(anisotropic=("b",), polarity=angle)`),
which lays stripes along the polarity (anisotropy on the activator A lays them across it;
measured by the structure tensor on 64x64 lattices: coherence 0.90-0.94 against 0.14 for the
isotropic model). Its `angle` is the stripes' direction in radians (0 along a row, toward
increasing row index positive). Orientations are modulo pi, so a fit searches the half-turn
centred on the target's own stripe direction (`orientation_bounds`): the answer is never at
a bound. `model="auto"` tries oriented families only on targets whose orientation coherence
is at least `ORIENTED_COHERENCE` (see `fitting._auto`).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Callable

import numpy as np

import morphojax as mj


@dataclasses.dataclass(frozen=True)
class Family:
    """One model family: its template, parameters and bounds, default fit, run and length scale.

    make(shape) -> a model, Experiment or one-species YoungCA whose compared field is `shape`;
    bounds: {name: (low, high, geometric)}; fit: parameters fitted by default; length:
    the parameter with wavelength ~ length ** length_power (None: none); steps, window,
    dt_cap: the run (steps per simulation, differentiated steps, largest time step);
    solver, stride: how a model family's runs are stepped (default forward Euler).
    """

    name: str
    make: Callable
    bounds: dict
    fit: tuple
    length: str | None = "scale"
    length_power: float = 0.5
    steps: int = 8000
    window: int = 1000
    dt_cap: float = 0.01
    description: str = ""
    # species whose diffusion follows the fitted `angle` (thesis eq. 4.8); () = isotropic
    anisotropic: tuple = ()
    # how a model family's runs are stepped (`fitting.Simulator`): None is forward Euler; a
    # solver takes one step of `stride` Euler steps, the same simulated time. A family
    # declares one only where `benchmarks/fit_solvers.py` finds its statistics within the
    # seed-to-seed spread of Euler's (benchmarks/results/fit_solvers.md)
    solver: object = None
    stride: int = 1
    # whether the design places its points at the target's wavelength by linear stability
    # where the prediction is valid (`fitting._predicted`); declared where
    # `benchmarks/fit_placement.py` finds placed points land within 10% of it after one run
    # at least as often as the scaling law's after two (benchmarks/results/fit_placement.md)
    predicted: bool = False

    @property
    def oriented(self) -> bool:
        """Whether the family lays its pattern along a fitted direction (`angle`)."""
        return bool(self.anisotropic)

    def parameters(self, shape=(32, 32)) -> list:
        """Every parameter name the family's template has (fittable or fixable)."""
        from ._simulator import Simulator

        return Simulator(self.make(tuple(shape)), shape=tuple(shape), steps=2, window=1,
                         anisotropic=self.anisotropic).parameter_names()

    def simulator(self, shape, template=None, *, steps: int | None = None, window: int | None = None,
                  **options):
        """The fit's forward model (`fitting.Simulator`) of this family on `shape`: its template
        (or `template`, a model of the family), its steps, differentiated window, time-step
        cap and anisotropic species, and its solver and stride where the stride divides the
        steps and window (a user's own that it does not divide run with forward Euler).
        `options` are further `Simulator` fields, and override these (`solver=None,
        stride=1` for forward Euler)."""
        from ._simulator import Simulator

        shape = tuple(shape)
        template = self.make(shape) if template is None else template
        steps = int(self.steps if steps is None else steps)
        window = int(min(self.window, steps) if window is None else window)
        stepping = {}
        if (self.solver is not None and isinstance(template, mj.AbstractModel) and not steps % self.stride
                and not window % self.stride):
            stepping = {"solver": self.solver, "stride": self.stride}
        return Simulator(template, **{"shape": shape, "steps": steps, "window": window, "dt_cap": self.dt_cap,
                                      "anisotropic": self.anisotropic, **stepping, **options})

    def default_bounds(self, name: str):
        """(low, high, geometric) of a parameter of this family, or None when it has none."""
        base = name.split(".")[-1]
        return self.bounds.get(name, self.bounds.get(base))


_TURING = {"ratio": (2.0, 50.0, True), "scale": (0.2, 8.0, True), "lower_a": (0.0, 5.0, False),
           "lower_b": (0.0, 6.0, False), "upper_a": (3.5, 12.0, False), "upper_b": (2.0, 20.0, False)}


def _leopard(shape):
    """The leopard paper's three phases (Figs. 13-17) scaled to a small lattice: Turing spots
    on a lattice of half the compared size (definition), then B copied to C, C reinforced
    while the lattice grows by division to the full size (development), then B and C
    reinforced while growth slows (maintenance). The compared species is C (the melanin's
    ring-forming part)."""
    rows, cols = (int(v) for v in shape)
    r0, c0 = max(8, rows // 2), max(8, cols // 2)
    # dt keeps every phase stable within the bounds below (largest diffusion ratio x scale = 48)
    define_steps, grow_steps, keep_steps, dt = 8000, 1500, 500, 0.005
    # expansions = rate x time (one row and column each), so the lattice reaches `shape`
    rate = (rows - r0) / (grow_steps * dt)
    cap = (rows + 4, cols + 4)
    turing = mj.Turing(30.0, 0.5, lower=(0.0, 2.0))
    reinforce = mj.Reinforcement(5.0, 5.0, 0.1)
    return mj.Experiment(
        name="leopard-small", initial=mj.Initial("paper", (r0, c0), capacity=cap),
        phases=(mj.Phase(turing, steps=define_steps, dt=dt, name="definition"),
                mj.Phase(mj.Composite((turing, reinforce)), steps=grow_steps, dt=dt, growth=mj.Growth(rate),
                         add_species=(("c", "b"),), name="development", capacity=cap),
                mj.Phase(mj.Composite((mj.Reinforcement(5.0, 5.0, 0.1), mj.Reinforcement(5.0, 5.0, 0.1))),
                         steps=keep_steps, dt=dt, keep=("b", "c"), name="maintenance", capacity=cap)),
        description="the leopard's definition, development and maintenance phases on a small lattice",
        show="c1")


FAMILIES = {
    "turing": Family(
        "turing", lambda shape: mj.Turing(), dict(_TURING), ("ratio", "scale", "lower_b"), predicted=True,
        description="the leopard paper's two-species Turing model with limits (eqs. 3-4)"),
    "anisotropic-turing": Family(
        "anisotropic-turing", lambda shape: mj.Turing(), {**_TURING, "angle": (-math.pi / 2, math.pi / 2, False)},
        ("ratio", "scale", "angle"), anisotropic=("b",),
        description="Turing's model with B diffusing along a polarity at a fitted angle: stripes along it "
                    "(thesis eq. 4.8, Fig. 5.13)"),
    "bard": Family(
        "bard", lambda shape: mj.preset("nudibranch").phases[0].model,
        {"alpha": (12.0, 20.0, False), "beta": (10.0, 14.0, False), "sp": (1e-3, 1.0, True),
         "diffusion_scale": (0.4, 3.0, True), "da": (1e-3, 10.0, True), "db": (1e-3, 10.0, True),
         "upper_a": (2.0, 12.0, False), "lower_a": (0.0, 5.0, False), "lower_b": (0.0, 6.0, False)},
        ("alpha", "beta", "diffusion_scale"), length="diffusion_scale", length_power=0.75, steps=3000, window=500,
        dt_cap=1.0,
        description="Bard's model (thesis listing), length through a common diffusion scale"),
    "gray-scott": Family(
        "gray-scott", lambda shape: mj.model_from_name("gray-scott"),
        {"feed": (0.01, 0.08, False), "kill": (0.045, 0.07, False), "diffusion_scale": (0.2, 1.5, True),
         "du": (0.02, 1.0, True), "dv": (0.01, 0.5, True)},
        ("feed", "kill", "diffusion_scale"), length="diffusion_scale", steps=5000, window=500, dt_cap=1.0,
        description="Gray-Scott (Pearson's scaling), length through a common diffusion scale"),
    "reinforcement": Family(
        "reinforcement", lambda shape: mj.Reinforcement(5.0, 5.0, 0.1),
        {"threshold": (2.0, 8.0, False), "width": (1.0, 8.0, True), "diffusion": (0.25, 0.8, True)},
        ("threshold", "width", "diffusion"), length="diffusion", length_power=2.0, steps=4000, window=500,
        dt_cap=0.05,
        description="single-reagent reinforcement (leopard paper eq. 6)"),
    "young": Family(
        "young", lambda shape: mj.YoungCA([(2.3, 6.01, 1.0, -0.3)], denominator=100),
        {"r_act": (1.5, 5.0, False), "r_inh": (3.0, 12.0, False), "w_inh": (-1.0, -0.05, False),
         "w_act": (0.2, 2.0, False)},
        ("r_act", "r_inh", "w_inh"), length=None, steps=30, window=10,
        description="Young's activator-inhibitor automaton (Dur 2023) through its soft relaxation "
                    "(fitting.Simulator): 30 steps from Young's sparse start; spots to stripes as w_inh rises"),
    "leopard": Family(
        "leopard", _leopard,
        {**_TURING, "definition:ratio": (10.0, 40.0, True), "definition:scale": (0.15, 1.2, True),
         "threshold": (2.0, 8.0, False), "width": (1.0, 8.0, True), "diffusion": (0.02, 1.0, True),
         "growth_rate": (1.0, 30.0, True)},
        ("definition:ratio", "definition:scale", "threshold"), length="definition:scale",
        steps=5000, window=300, description="the leopard's three-phase growing experiment (rosettes)"),
}


def structure_tensor(field) -> tuple[float, float, float]:
    """(Jxx, Jyy, Jxy): the field's mean structure tensor from central differences inside the
    field (a photo does not wrap around); x along a row, y along a column."""
    z = np.asarray(field, np.float64)
    gx = 0.5 * (z[1:-1, 2:] - z[1:-1, :-2])  # along a row (+x, increasing column)
    gy = 0.5 * (z[2:, 1:-1] - z[:-2, 1:-1])  # along a column (increasing row)
    return float(np.mean(gx * gx)), float(np.mean(gy * gy)), float(np.mean(gx * gy))


def stripe_angle(field) -> tuple[float, float]:
    """(direction, coherence) of a field's stripes from its structure tensor: the direction
    in radians in [-pi/2, pi/2) (0 along a row, positive toward increasing row index,
    the polarity's convention) runs across the mean gradient; coherence in [0, 1] is 0 for
    an isotropic texture and 1 for straight parallel stripes."""
    jxx, jyy, jxy = structure_tensor(field)
    norm = jxx + jyy
    if norm <= 0:
        return 0.0, 0.0
    gradient = 0.5 * math.atan2(2.0 * jxy, jxx - jyy)
    direction = (gradient + math.pi) % math.pi - math.pi / 2  # gradient + pi/2, wrapped into [-pi/2, pi/2)
    return float(direction), float(math.hypot(jxx - jyy, 2.0 * jxy) / norm)


def orientation_bounds(direction: float) -> tuple:
    """Bounds of a fitted `angle`: the half-turn centred on a stripe direction (radians)."""
    return (direction - math.pi / 2, direction + math.pi / 2, False)


def family(name: str) -> Family:
    """The family called `name` (a ValueError lists the known ones)."""
    if name not in FAMILIES:
        raise ValueError(f"unknown model family {name!r}; allowed: {', '.join(FAMILIES)} or 'auto'")
    return FAMILIES[name]


def family_of(model) -> Family | None:
    """The family whose template has the same structure as `model` (a model object), if any."""
    if isinstance(model, str):
        return FAMILIES.get(model)
    for fam in FAMILIES.values():
        tmpl = fam.make((32, 32))
        if type(tmpl) is type(model) and not isinstance(model, (mj.Experiment, mj.Composite)):
            return fam
    return None
