"""Running an `Experiment`: its phases in order, snapshots, checkpoints and resuming.

`run_experiment` steps each phase of an experiment (`morphojax._experiment`, its plain
data) from the initial state, writes a checkpoint every so many steps (atomically: a crash
never destroys the last good one), and resumes from one exactly: the same keys are drawn
from where the checkpoint stands as the uninterrupted run would draw (see the key rule in
`morphojax._experiment`). The `Result` carries the final state, the experiment and the
metadata needed to reproduce it.
"""

from __future__ import annotations

import dataclasses
import json
import time
from pathlib import Path

import jax

from ._checks import check_range, is_concrete
from ._experiment import Experiment, Phase
from ._files import dumps
from ._growing_mesh import MeshGrowth
from ._serialise import key_from_data, key_to_data, load_npz, save_npz
from ._simulate import rollout, simulate
from ._state import State
from ._version import __version__


@dataclasses.dataclass
class Result:
    """What `run_experiment` returns: the final state, the experiment, snapshots and timings.

    frames: list of (label, State) snapshots (when asked for), in order.
    metadata: everything saved next to the arrays (seed, phase, steps, timings...).
    """

    state: State
    experiment: Experiment
    frames: list
    metadata: dict

    def image(self, scale: int = 1):
        """The final picture as a PIL image, rendered as the experiment shows it; `scale` pixels per lattice cell."""
        from ._render import render_experiment

        return render_experiment(self.state, self.experiment, scale=scale)

    def save(self, path) -> Path:
        """Write the result `.npz` (final species cropped to the active lattice, state, metadata); returns the path."""
        return save_npz(path, self.state, self.metadata)

    def describe(self):
        """`describe` of the final pattern the experiment shows (B for the melanin texture),
        periodic when the last phase wraps: its class, spots, holes, wavelength."""
        from ._descriptors import describe

        exp = self.experiment
        shown = self.state.array("b" if exp.show == "melanin" else exp.show)
        return describe(shown, wrap=exp.phases[-1].boundary == "wrap")


def check_progress(experiment: Experiment, meta: dict) -> None:
    """Refuse a checkpoint of `experiment` whose step disagrees with where its run says it
    stands. Every phase takes exactly its `steps` unless it stops at a steady state or steps
    adaptively, so up to the first such phase the state's step is the steps of the phases
    done plus `phase_step`: a checkpoint claiming more phases done than its state ran
    (a tampered `phase`) is refused here instead of being written out as the final result."""
    run, step = meta.get("run") or {}, meta.get("step")
    if step is None:
        return
    phase, phase_step = int(run.get("phase", 0)), int(run.get("phase_step", 0))
    done = experiment.phases[:phase + 1] if phase < len(experiment.phases) else experiment.phases
    if any(p.until is not None or getattr(p.solver, "adaptive", False) for p in done):
        return
    expected = sum(p.steps for p in experiment.phases[:phase]) + phase_step
    if int(step) != expected:
        raise ValueError(f"run fields 'phase' ({phase}) and 'phase_step' ({phase_step}) put this checkpoint at step "
                         f"{expected} of its experiment, but metadata field 'step' is {step}: the file disagrees "
                         "with itself")


def run_experiment(experiment: Experiment, seed: int = 0, *, key=None, frames: bool = False,
                   progress: bool = False, checkpoint_path=None, checkpoint_every: int | None = None, resume=None,
                   stop_after: int | None = None, grad_window: int | None = None, throw: bool = True) -> Result:
    """Run every phase of `experiment` from its initial state (or resume a checkpoint).

    Pure in (experiment, key) like `simulate`: usable under `jax.jit`, `jax.vmap` and
    `jax.grad` (with frames, checkpoints and progress off).

    Args:
        seed: the run's random seed; the same seed gives the same result.
        key: a `jax.random` key to use instead of `seed` (e.g. a traced key under vmap).
        frames: keep each phase's snapshots (`Phase.frames` of them) in `Result.frames`.
        progress: progress bars (per phase).
        checkpoint_path / checkpoint_every: write an `.npz` checkpoint every N steps (and at
            phase ends) that `resume` accepts.
        resume: a checkpoint path (or (State, metadata) from `load_npz`) to continue from; the
            result equals that of an uninterrupted run with the same seed (or key: a run
            started with `key=` records it, and resumes with it unless given another).
        stop_after: stop after this many steps in total (for tests of resuming).
        grad_window: differentiate only through the last `grad_window` steps of the run; the
            state before them is treated as a constant (truncated backpropagation, see the
            fitting documentation for why long horizons need it).
        throw: raise `SimulationError` when a phase blows up or overflows its capacity (as
            `simulate`); False returns the state as it is (a fit scores such a point as bad
            instead of stopping).
    """
    if stop_after is not None:
        check_range(stop_after, "run_experiment.stop_after (steps)", low=1)
    if checkpoint_every is not None:
        check_range(checkpoint_every, "run_experiment.checkpoint_every (steps)", low=1)
    if resume is not None:
        state, meta = load_npz(resume) if not isinstance(resume, tuple) else resume
        saved = meta.get("experiment")
        if saved is not None and is_concrete([p.model for p in experiment.phases]) and \
                _what_runs(saved) != _what_runs(experiment.to_dict()):
            raise ValueError(
                f"run_experiment.resume: the checkpoint was written by another experiment "
                f"({saved.get('name')!r}, or the same one with other parameters) than {experiment.name!r}; "
                "resume it with mj.load_experiment(meta), as `morphojax resume` does"
            )
        check_progress(experiment, meta)
        run = meta.get("run", {})
        seed = int(run["seed"]) if run.get("seed") is not None else seed
        key = key_from_data(run.get("key")) if key is None else key
        start_phase, phase_step = int(run.get("phase", 0)), int(run.get("phase_step", 0))
        origin = run.get("phase_origin")
    else:
        start_phase, phase_step, origin = 0, 0, None
    root = jax.random.key(int(seed)) if key is None else key
    record = {"seed": int(seed)} if key is None else {"seed": None, "key": key_to_data(key)}
    if resume is None:
        state = experiment.initial.build(jax.random.fold_in(root, 0))
    steps_before = sum(p.steps for p in experiment.phases[:start_phase])
    window_start = None if grad_window is None else max(0, experiment.total_steps - int(grad_window))
    done_total = 0
    snapshots: list = []
    timings = []
    t_start = time.perf_counter()
    for i in range(start_phase, len(experiment.phases)):
        phase = experiment.phases[i]
        if phase_step == 0:
            state = phase.prepare(state)
            origin = int(state.step) if is_concrete(state.step) else state.step
        kwargs = dict(domain=phase.domain, bounds=phase.bounds, growth=phase.growth, solver=phase.solver,
                      until=phase.until,
                      sources=phase.sources, key=jax.random.fold_in(root, i + 1), origin=origin, throw=throw,
                      progress=(phase.name or f"phase {i + 1}") if progress else False)
        marks = set(_frame_steps(phase)) if frames and phase.frames else set()
        saves = set(range(phase_step + checkpoint_every, phase.steps, checkpoint_every)) if checkpoint_every else set()
        cuts = {phase.steps} | marks | saves
        if stop_after is not None:
            cuts.add(phase_step + max(0, stop_after - done_total))
        if window_start is not None and steps_before < window_start < steps_before + phase.steps:
            cuts.add(window_start - steps_before)
        t0 = time.perf_counter()
        simple = (phase_step == 0 and cuts == {phase.steps} | marks and checkpoint_path is None and stop_after is None
                  and window_start is None and phase.until is None and not getattr(phase.solver, "adaptive", False)
                  and not isinstance(phase.growth, MeshGrowth))  # a growing mesh's snapshots differ in shape
        every = _even_spacing(marks, phase.steps) if simple else None
        if every is not None:
            # evenly spaced snapshots and nothing else to stop for: one rollout takes them
            # all in one compiled call (simulating piece by piece compiles a growing phase's
            # every piece anew: its lattice, and so its plan, differs from piece to piece),
            # and the key schedule makes its states those of the pieces
            n = phase.steps // every
            state, taken = rollout(phase.model, state, n * every, phase.dt, every, **kwargs)
            snapshots += [(f"{phase.name or f'phase {i + 1}'} step {(j + 1) * every}", taken.frame(j))
                          for j in range(n)]
            done_total += n * every
            phase_step = n * every
        for cut in sorted(c for c in cuts if phase_step < c <= phase.steps):
            state = simulate(phase.model, state, cut - phase_step, phase.dt, **kwargs)
            done_total += cut - phase_step
            phase_step = cut
            if window_start is not None and steps_before + cut <= window_start:
                state = jax.lax.stop_gradient(state)
            if cut in marks:
                snapshots.append((f"{phase.name or f'phase {i + 1}'} step {cut}", state))
            at_end = cut == phase.steps
            if checkpoint_path is not None and (cut in saves or at_end):
                _write(checkpoint_path, state, experiment, record, i + 1 if at_end else i, 0 if at_end else cut,
                       origin, timings)
            if stop_after is not None and done_total >= stop_after and not at_end:
                timings.append({"phase": phase.name or str(i + 1), "steps": cut, "seconds": time.perf_counter() - t0})
                return Result(state, experiment, snapshots, _meta(experiment, record, i, cut, origin, timings))
        timings.append({"phase": phase.name or str(i + 1), "steps": phase.steps, "seconds": time.perf_counter() - t0})
        steps_before += phase.steps
        phase_step = 0
        if stop_after is not None and done_total >= stop_after and i + 1 < len(experiment.phases):
            return Result(state, experiment, snapshots, _meta(experiment, record, i + 1, 0, origin, timings))
    meta = _meta(experiment, record, len(experiment.phases), 0, origin, timings)
    meta["run"]["seconds"] = time.perf_counter() - t_start
    return Result(state, experiment, snapshots, meta)


def _what_runs(data: dict) -> dict:
    """The parts of an experiment's plain data that decide its result (its initial state and
    phases, less their names and snapshot settings), normalised through JSON."""
    # a lattice is said twice (its shorthands and its domain); files written before domains
    # existed have only the shorthands, so the shorthands decide
    def decides(p):
        lattice = (p.get("domain") or {}).get("type", "Lattice") == "Lattice"
        return {k: v for k, v in p.items() if k not in ("name", "frames") and not (k == "domain" and lattice)}

    phases = [decides(p) for p in data["phases"]]
    return json.loads(dumps({"initial": data["initial"], "phases": phases}))


def _even_spacing(marks: set, steps: int) -> int | None:
    """The spacing of snapshot steps that are every k-th step from k on (the rest of the
    phase, under k steps, after the last), else None."""
    if not marks:
        return None
    every = min(marks)
    return every if marks == set(range(every, steps + 1, every)) else None


def _frame_steps(phase: Phase) -> list[int]:
    """The phase steps after which snapshots are taken."""
    if isinstance(phase.frames, (tuple, list)):
        return sorted(int(m) for m in phase.frames if 0 < int(m) <= phase.steps)
    if phase.frames <= 0 or phase.steps <= 0:
        return []
    every = max(1, phase.steps // int(phase.frames))
    return list(range(every, phase.steps + 1, every))


def _meta(experiment, record, phase, phase_step, origin, timings):
    """`record`: {"seed": int} for a run from a seed, {"seed": None, "key": words} from a key."""
    # under jit/vmap/grad the parameters are tracers: there is nothing concrete to record
    concrete = is_concrete([p.model for p in experiment.phases], [p.growth for p in experiment.phases])
    return {
        "morphojax": __version__,
        "experiment": experiment.to_dict() if concrete else None,
        "run": {**record, "phase": int(phase), "phase_step": int(phase_step),
                "phase_origin": int(origin) if origin is not None and is_concrete(origin) else None,
                "timings": timings},
    }


def _write(path, state, experiment, record, phase, phase_step, origin, timings):
    save_npz(path, state, _meta(experiment, record, phase, phase_step, origin, timings))
