"""A design point placed at the target's wavelength before it is simulated: the linear
stability's fastest-growing wavelength (`mj.dispersion`) along the family's length parameter.

The global design draws points across the bounds and brings each to the target's wavelength
along the family's length parameter (`fitting._fit`). By the family's scaling law alone
(wavelength ~ length ** `Family.length_power`) that takes two simulations a point: one to
measure where its pattern settles, one at the length the law then gives. Where the
homogeneous state is Turing-unstable, linear stability predicts the wavelength without a run,
so the point is placed first and simulated once; the measured move runs only where the
placed point settled more than LANDED (5%) away from the target's wavelength.

A point is placed only where:
- its family declares it (`Family.predicted`: where `benchmarks/fit_placement.py` finds placed
  points landing as often after one run as the law's after two; `turing` only);
- the template is a model of two or more species with scalar parameters, stepped on an
  isotropic lattice (not an automaton, an experiment, one species, parameter maps, or an
  oriented family's polarised lattice, whose stencil's waves are not its modes);
- the steady state converged, lies off every saturation limit (the clamp is not in the
  linearisation; on a limit the state forms no pattern or a clipped one), is stable
  without diffusion and unstable with it, and its fastest wavelength is finite and at most
  the lattice's shorter side;
- the design is a Latin hypercube (a grid's levels along the length would all be placed at
  one value).
Elsewhere (Bard, whose one valid point of 16 formed no measurable pattern once placed;
Gray-Scott's stable trivial state; a Turing point with B held on `lower_b`; Young;
reinforcement; the leopard experiment; anisotropic Turing) the point is moved by the law as
before.

The wavelength is the continuum's: the fastest of `Dispersion.curve`'s growth rates over a
log grid of WAVENUMBER_STEPS wavenumbers across [2 pi / (4 x the longer side), pi] (at most
1% apart on lattices whose longer side is at most 200 cells), so it moves smoothly with the
parameters where the lattice's own modes (`fastest_wavelength`) jump from one discrete wave
to the next (64 / 6 to 64 / 7 cells: 15%). The nine-point stencil shortens waves of 10 cells
by a few percent against the continuum; the settled pattern's wavelength differs from the
linear one too (`benchmarks/results/stability.md`). Both are left to the measured move. The
length is found by two secant steps in log-log (the local power of wavelength against
length, probed at twice the length): for a length that multiplies every diffusion rate, as
all of the families' do, the continuum wavelength goes exactly as its square root and the
first step lands.

Measured before `turing` declared it (`benchmarks/results/fit_placement.md`: 16 Latin-hypercube
points of its bounds for targets of 8, 10 and 13 cells, 2 seeds): 27 of the 48 have a valid
prediction; placed, 93% of them settle within 10% of the target's wavelength after one run,
as many as the law's moves after two, at 1.44 runs a placed point instead of 2.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

import morphojax as mj

PROBE = 2.0  # the local power is measured between a length and PROBE times it
WAVENUMBER_STEPS = 600  # log-spaced over 2 x the longer side's range: at most 1% apart up to 200 cells
SECANT_STEPS = 2
LANDED = 0.05  # a placed point that settled within 5% of the target's wavelength is not moved


def applies(sim) -> bool:
    """Whether linear stability can place `sim`'s design points: a model of two or more
    species with scalar parameters on an isotropic lattice (module docstring)."""
    template = sim.template
    if not (isinstance(template, mj.AbstractModel) and not sim.anisotropic and template.n_species >= 2):
        return False
    # one homogeneous state: no parameter maps (`parameters()` names each limit apart)
    return all(np.size(value) == 1 for value in template.parameters().values())


def _wavenumbers(shape) -> jnp.ndarray:
    longest = max(int(n) for n in shape)
    return jnp.geomspace(2 * np.pi / (4 * longest), np.pi, WAVENUMBER_STEPS)


@eqx.filter_jit
def _predict(sim, names: tuple, thetas):
    """(wavelength, valid) of each row of `thetas` (natural units, one column per name)."""
    ks = _wavenumbers(sim.shape)
    shorter = min(int(n) for n in sim.shape)

    def one(theta):
        model = sim.build({n: theta[i] for i, n in enumerate(names)})
        d = mj.dispersion(model, mj.Lattice(sim.stencil, sim.boundary), tuple(sim.shape))
        rates = d.curve(ks)
        wavelength = 2 * jnp.pi / ks[jnp.argmax(rates)]
        valid = (d.converged & d.turing_unstable & ~jnp.any(d.at_limit) & (jnp.max(rates) > 0)
                 & jnp.isfinite(wavelength) & (wavelength <= shorter))
        return wavelength, valid

    return jax.vmap(one)(thetas)


def predicted_wavelengths(sim, names, thetas) -> tuple[np.ndarray, np.ndarray]:
    """The linear prediction's wavelength (cells) at each row of `thetas` and whether it is
    valid there (module docstring); NumPy arrays."""
    wavelength, valid = _predict(sim, tuple(names), jnp.asarray(thetas, jnp.float32))
    valid = np.array(valid)
    return np.where(valid, np.asarray(wavelength, np.float64), np.nan), valid


def place(sim, names, thetas, length: int, target_wavelength: float, low: float,
          high: float) -> tuple[np.ndarray, np.ndarray]:
    """`thetas` with column `length` moved so the predicted wavelength is the target's
    (clipped to [low, high]), and which rows were placed: those whose prediction is valid at
    the start and at every point tried. Rows not placed are returned unchanged."""
    thetas = np.asarray(thetas, np.float64)
    placed = thetas.copy()
    wavelength, valid = predicted_wavelengths(sim, names, placed)
    if not (np.isfinite(target_wavelength) and target_wavelength > 0) or not valid.any():
        return thetas, np.zeros(len(thetas), bool)
    for _ in range(SECANT_STEPS):
        probe = placed.copy()
        probe[:, length] = placed[:, length] * PROBE
        far, far_valid = predicted_wavelengths(sim, names, probe)
        with np.errstate(divide="ignore", invalid="ignore"):
            power = np.log(far / wavelength) / np.log(PROBE)
        valid &= far_valid & (power > 0)
        with np.errstate(divide="ignore", invalid="ignore"):
            factor = (target_wavelength / wavelength) ** (1.0 / power)
        placed[:, length] = np.where(valid, np.clip(placed[:, length] * factor, low, high), placed[:, length])
        wavelength, now_valid = predicted_wavelengths(sim, names, placed)
        valid &= now_valid
    return np.where(valid[:, None], placed, thetas), valid
