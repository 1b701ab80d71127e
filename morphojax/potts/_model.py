"""`Potts`: the cellular Potts model of Tinson 2022 (section III.B, after Graner & Glazier
1992), its Hamiltonian and its Metropolis run.

    H = sum over neighbouring sites i, j of J(tau(sigma_i), tau(sigma_j)) (1 - delta(sigma_i, sigma_j))
        + lambda sum over cells sigma of (v(sigma) - V)^2

(the paper prints the volume sum inside the contact sum's bracket; it is the separate term
of CompuCell3D's Volume plugin, appendix C2). Energies are in the units of J; the
temperature T is in the same units, lambda in units of J per site^2, V in sites. A copy
attempt picks a target site and one of its neighbours, proposes copying the neighbour's id
onto the target, and accepts with probability min(1, exp(-dH / T)) (T = 0: only dH <= 0).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._checks import as_float_array, check_choice, check_count, check_finite, check_range, is_concrete
from ._state import PottsState
from ._sweep import even_lattice, from_colour_major, run_mcs, run_mcs_dynamic, to_colour_major, total_energy

BOUNDARIES = ("fixed", "wrap")  # fixed: sites beyond the edge do not exist (CompuCell3D's default)


class Potts(eqx.Module):
    """A cellular Potts model.

    - `J`: (types x types) adhesion energies, index 0 the medium (symmetric, finite);
    - `temperature`: T >= 0 of the Boltzmann acceptance exp(-dH / T);
    - `target_volume`: V > 0 (sites) of every cell;
    - `volume_weight`: lambda >= 0 of the volume term lambda (v - V)^2;
    - `order`: neighbour order (static): 1 = the 4 nearest, 2 = the 8 of the Moore
      neighbourhood; both the contact sum and the copy sources use it (CompuCell3D's
      NeighborOrder);
    - `boundary`: "fixed" (the default: no sites beyond the edge) or "wrap" (toroidal; needs
      even sides).

    Tinson's (2022) runs: `Potts.paper003(j_like)` (J = 16 between unlike types and with the
    medium, 0 medium-medium, T = 10, V = 25, lambda = 2, order 2).

    Energies are exact in floating point whenever J, lambda and V are multiples of 2^-k and
    the totals stay below 2^(24-k) in float32 (the paper's halves: below 8 million).
    """

    J: jax.Array
    temperature: jax.Array
    target_volume: jax.Array
    volume_weight: jax.Array
    order: int = eqx.field(static=True)
    boundary: str = eqx.field(static=True)

    def __init__(self, J, temperature, target_volume, volume_weight, order=2, boundary="fixed"):
        self.J = as_float_array(J, "Potts.J")
        self.temperature = as_float_array(temperature, "Potts.temperature")
        self.target_volume = as_float_array(target_volume, "Potts.target_volume")
        self.volume_weight = as_float_array(volume_weight, "Potts.volume_weight")
        self.order = order
        self.boundary = boundary

    def __check_init__(self):
        if self.J.ndim != 2 or self.J.shape[0] != self.J.shape[1] or self.J.shape[0] < 2:
            raise ValueError(f"Potts.J must be a square (types x types) matrix with the medium at index 0 and at "
                             f"least one cell type (got shape {self.J.shape})")
        check_finite(self.J, "Potts.J")
        if is_concrete(self.J) and not np.array_equal(np.asarray(self.J), np.asarray(self.J).T):
            raise ValueError("Potts.J must be symmetric (J[p, q] = J[q, p]: adhesion between types p and q)")
        for name in ("temperature", "target_volume", "volume_weight"):
            if getattr(self, name).ndim != 0:
                raise ValueError(f"Potts.{name} must be a scalar (got shape {getattr(self, name).shape})")
        check_finite(self.temperature, "Potts.temperature")
        check_range(self.temperature, "Potts.temperature", low=0)
        check_finite(self.target_volume, "Potts.target_volume")
        check_range(self.target_volume, "Potts.target_volume", low=0, low_open=True)
        check_finite(self.volume_weight, "Potts.volume_weight")
        check_range(self.volume_weight, "Potts.volume_weight", low=0)
        if self.order not in (1, 2):
            raise ValueError(f"Potts.order must be 1 (4 nearest neighbours) or 2 (Moore, 8) (got {self.order!r})")
        check_choice(self.boundary, "Potts.boundary", BOUNDARIES)

    @staticmethod
    def paper003(j_like, temperature=10.0, j_unlike=16.0, j_medium=16.0, target_volume=25.0, volume_weight=2.0):
        """Tinson's (2022) model (section III.B.2, appendix C2): types medium, 1 (condensing),
        2 (non-condensing); J(1, 1) = J(2, 2) = `j_like`, J(1, 2) = `j_unlike`, J(M, 1) =
        J(M, 2) = `j_medium`, J(M, M) = 0."""
        m, u, like = j_medium, j_unlike, j_like
        J = jnp.array([[0.0, m, m], [m, like, u], [m, u, like]], dtype=jnp.result_type(float))
        return Potts(J, temperature, target_volume, volume_weight, order=2, boundary="fixed")

    def energy(self, state: PottsState) -> jax.Array:
        """The total Hamiltonian H of `state` (a scalar in the units of J)."""
        self._check_state(state)
        return _energy(self, state.ids, state.types, state.volumes)

    def run(self, state: PottsState, mcs: int, key, *, energy: bool = False):
        """`mcs` Monte Carlo steps from `state` with the `jax.random` key `key` (same key,
        same lattice). Returns the final `PottsState`, or with `energy=True` the pair
        (state, H after each MCS): H of the start plus the running sum of the applied
        changes, each priced exactly (see `_sweep`)."""
        check_count(mcs, "mcs", "Monte Carlo steps")
        self._check_state(state)
        if self.boundary == "wrap" and (state.shape[0] % 2 or state.shape[1] % 2):
            raise ValueError(f"Potts.boundary 'wrap' needs an even number of rows and columns (got {state.shape}): "
                             "the four-colour sub-lattices must not touch across the seam")
        rows, cols = state.shape
        if not energy:  # one compiled loop for every number of MCS
            planes, volumes = _run_dynamic(self, state.ids, state.volumes, state.types, key, jnp.int32(mcs))
            return PottsState(from_colour_major(planes)[:rows, :cols], state.types, volumes)
        planes, volumes, d_e, _ = _run(self, state.ids, state.volumes, state.types, key, int(mcs))
        out = PottsState(from_colour_major(planes)[:rows, :cols], state.types, volumes)
        return out, self.energy(state) + jnp.cumsum(d_e)

    def _check_state(self, state):
        if not isinstance(state, PottsState):
            raise ValueError(f"state must be a PottsState (got {type(state).__name__})")
        if is_concrete(state.types) and int(state.types.max()) >= self.J.shape[0]:
            raise ValueError(f"PottsState.types must lie in [0, {self.J.shape[0] - 1}] for a J of shape "
                             f"{self.J.shape} (got max {int(state.types.max())})")


_energy = eqx.filter_jit(total_energy)


@eqx.filter_jit
def _run(model, ids, volumes, types, key, mcs):
    planes = to_colour_major(even_lattice(ids, model.boundary))
    return run_mcs(model, planes, volumes, types, key, mcs)


@eqx.filter_jit
def _run_dynamic(model, ids, volumes, types, key, mcs):
    planes = to_colour_major(even_lattice(ids, model.boundary))
    return run_mcs_dynamic(model, planes, volumes, types, key, mcs)
