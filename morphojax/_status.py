"""How a run ended: ok, non-finite at step n, growth past the capacity, or settled at time t.

In the manner of optimistix's `RESULTS` and `throw=`: the compiled loop records what went
wrong as arrays (so failed members of a vmapped sweep are recorded, not raised), and one
place turns that record into an error or a message.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
from jax import Array

from ._checks import is_concrete


def _array(value):
    """`value` as a JAX array: arrays (and tracers) as they are, numbers put on the device."""
    return value if isinstance(value, jax.Array) else jnp.asarray(value)


class SimulationError(ValueError):
    """A run that went wrong: non-finite values (with the step), or growth past capacity."""


class RunStatus(eqx.Module):
    """What the loop recorded about a run.

    Attributes:
        nonfinite_step: int32, the first step whose result held NaN or Inf; -1 if none.
        overflow: bool, growth was due while the state's capacity was full.
        steady_at: the simulated time at which a stopping rule (`until=SteadyState(...)`)
            ended the run; NaN if it did not (or none was given). An array, as the other
            fields, so that it works under `jit` and `vmap`.
        steps_taken: the steps the run made: `steps` for a fixed step, fewer when a
            stopping rule ended it, and the accepted steps of an adaptive solver.
        incomplete: bool, an adaptive run stopped short of its time: `max_steps` attempts
            did not reach it, or its step fell below 1e-9 of the span (the state's time
            says where it got to).

    Works under `vmap` (the attributes then carry the batch axes). The fields are JAX
    arrays even in an eager call: `bool(status.ok)` and `status.message()` give the Python view.
    """

    nonfinite_step: Array
    overflow: Array
    steady_at: Array
    steps_taken: Array
    incomplete: Array

    def __init__(self, nonfinite_step, overflow, steady_at=float("nan"), steps_taken=0, incomplete=False):
        self.nonfinite_step = _array(nonfinite_step)
        self.overflow = _array(overflow)
        self.steady_at = _array(steady_at)
        self.steps_taken = _array(steps_taken)
        self.incomplete = _array(incomplete)

    @classmethod
    def healthy(cls) -> "RunStatus":
        return cls(jnp.asarray(-1, jnp.int32), jnp.asarray(False))

    @property
    def ok(self):
        """True where the run neither blew up, overflowed nor stopped short of its time: a
        Python bool for one eager run, an array under `jit` or for a batch (`vmap`)."""
        if is_concrete(self) and all(jnp.ndim(v) == 0 for v in (self.nonfinite_step, self.overflow, self.incomplete)):
            # one eager run: read on the host (no device operations), as `message` does
            return int(self.nonfinite_step) < 0 and not bool(self.overflow) and not bool(self.incomplete)
        ok = (self.nonfinite_step < 0) & ~self.overflow & ~self.incomplete
        return bool(ok) if is_concrete(ok) and jnp.ndim(ok) == 0 else ok

    def merge(self, later: "RunStatus") -> "RunStatus":
        """This status followed by a later piece's: the first blow-up step, any overflow."""
        step = jnp.where(self.nonfinite_step >= 0, self.nonfinite_step, later.nonfinite_step)
        steady = jnp.where(jnp.isnan(self.steady_at), later.steady_at, self.steady_at)
        return RunStatus(step, self.overflow | later.overflow, steady, self.steps_taken + later.steps_taken,
                         self.incomplete | later.incomplete)

    def message(self, start=None) -> str:
        """The status in words (concrete values); with `start`, the state's step when the
        call began, a blow-up is also counted from the call's own first step."""
        if int(self.nonfinite_step) >= 0:
            n = int(self.nonfinite_step)  # the state's step count once that step was taken (1 = the first)
            where = f"step {n}"
            if start is not None and is_concrete(start):
                where += f" (step {n - int(start)} of this call)"
            return (f"the state became non-finite (NaN or Inf) at {where}: the run blew up (with an IMEX solver "
                    "off the transforms, a conjugate-gradient solve that did not converge ends the same way). "
                    "Reduce dt, check the parameters, or use throw=False to get the state anyway.")
        if bool(self.overflow):
            return "growth exceeded the state's capacity during the run"
        if bool(self.incomplete):
            return (f"the adaptive run stopped short of its time after {int(self.steps_taken)} steps: its max_steps "
                    "attempts did not reach it, or its step size fell below 1e-9 of the span. Loosen rtol/atol, "
                    "raise max_steps, or use a fixed dt; throw=False returns the state where it got to.")
        return "ok"

    def check(self, state, throw: bool, start=None):
        """`state` as it is, after raising `SimulationError` for a failed run when `throw`
        (`start`: the state's step when the call began, for the message).

        Eagerly the error names the step; inside `jit` it becomes an `eqx.error_if` on the
        state's fields (a runtime error without the step).
        """
        if not throw:
            return state
        if is_concrete(self.nonfinite_step, self.overflow, self.incomplete):
            if not bool(self.ok):
                raise SimulationError(self.message(start))
            return state
        fields = eqx.error_if(state.fields, self.nonfinite_step >= 0,
                              "the state became non-finite (NaN or Inf) during the run; "
                              "run eagerly (outside jit) to get the step, or pass throw=False")
        fields = eqx.error_if(fields, self.overflow, "growth exceeded the state's capacity during the run")
        fields = eqx.error_if(fields, self.incomplete, "the adaptive run stopped short of its time; run eagerly for "
                                                       "the details, or pass throw=False")
        return eqx.tree_at(lambda s: s.fields, state, fields)


class Run(eqx.Module):
    """What `run_status` returns: the final state and how the run ended.

    Unpacks as (state, nonfinite_step, overflow), as a tuple did before stopping rules;
    `steady_at` is the simulated time a stopping rule ended the run (NaN if it did not),
    `steps_taken` the steps it made, `incomplete` whether an adaptive run stopped short
    of its time, and `run.status` the whole `RunStatus`.
    """

    state: object
    nonfinite_step: Array
    overflow: Array
    steady_at: Array
    steps_taken: Array
    incomplete: Array

    def _fields(self):
        return (self.state, self.nonfinite_step, self.overflow)

    def __iter__(self):
        return iter(self._fields())

    def __getitem__(self, index):
        return self._fields()[index]

    def __len__(self):
        return 3

    @property
    def status(self) -> RunStatus:
        return RunStatus(self.nonfinite_step, self.overflow, self.steady_at, self.steps_taken, self.incomplete)
