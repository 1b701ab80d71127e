"""Stopping rules: run until the pattern has settled, not for a fixed count.

The thesis stops a simulation automatically when the largest absolute change of any
concentration in one iteration falls below a tolerance (section 5.2.5). Here the change is
per unit simulated time, max |x_{n+1} - x_n| / dt, so the same tolerance means the same
thing at every dt and with every solver.
"""

from __future__ import annotations

import equinox as eqx

from .._checks import check_finite, check_range


class SteadyState(eqx.Module):
    """Stop when max |x_{n+1} - x_n| / dt over every species and active cell is below `tol`.

    `simulate(..., until=mj.SteadyState(tol=1e-4))`: `steps` is then the most steps the
    run may take, and `RunStatus.steady_at` (via `run_status`) the simulated time at which
    it stopped (NaN if it did not). The step that measured the small change is kept.

    Inside `jit` the run checks after every step and ends at the first whole chunk of
    steps (128 by default) after the stop, skipping the rest; under `vmap` every member
    stops on its own step (a finished member is frozen) and the batch ends when all have
    stopped. Reverse-mode gradients go through a checkpointed loop (equinox's
    `while_loop(kind="checkpointed")`, bounded by `steps`); the stopping step itself is not
    differentiated (it is piecewise constant in the parameters). Forward mode (`jax.jvp`)
    is not supported with a stopping rule. With `rollout` the run cannot end early: the
    frames after the stop repeat the settled state.
    """

    tol: float = eqx.field(static=True)

    def __init__(self, tol: float = 1e-4):
        check_finite(tol, "SteadyState.tol")
        check_range(tol, "SteadyState.tol", low=0.0, low_open=True)
        self.tol = float(tol)

    def to_dict(self) -> dict:
        return {"until": "steady-state", "tol": self.tol}
