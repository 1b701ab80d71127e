"""Solvers: convergence order, time to a pattern on fig4-r40, and every static gallery preset.

    python benchmarks/bench_solvers.py --convergence      # order plot, float64 (a minute)
    python benchmarks/bench_solvers.py --fig4 --repeats 5 # time to solution, 5 processes
    python benchmarks/bench_solvers.py --presets          # every eligible preset, one process

Time to solution is the compiled run to the preset's simulated time (compilation in its
own column: the first call minus the second). "Same pattern" means the final descriptors
of the shown species match the Euler run's: wavelength within 3%, the same class, spot
count within 10% (the solvers issue's criteria). Results go to benchmarks/results/solvers.md
(sections replaced by the mode that made them) and solvers_convergence.png.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import re
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE), str(HERE.parent / "tests")]
from _harness import in_fresh_processes, machine, markdown_table, median  # noqa: E402

RESULTS = HERE / "results"
REPORT = RESULTS / "solvers.md"


def solvers():
    import morphojax as mj
    return {"ETDRK1": mj.ETDRK(1), "ETDRK2": mj.ETDRK(2), "ETDRK4": mj.ETDRK(4), "IMEX1": mj.IMEX(1),
            "IMEX2": mj.IMEX(2)}


def same_pattern(ref, got) -> tuple[bool, str]:
    """The issue's criteria, with the reason when they fail."""
    if got.pattern != ref.pattern:
        return False, f"class {got.pattern} (Euler: {ref.pattern})"
    if np.isfinite(ref.wavelength) and abs(got.wavelength / ref.wavelength - 1) > 0.03:
        return False, f"wavelength {got.wavelength:.2f} (Euler: {ref.wavelength:.2f})"
    if ref.spots >= 5 and abs(got.spots / ref.spots - 1) > 0.10:
        return False, f"{got.spots} spots (Euler: {ref.spots})"
    return True, ""


# ---- convergence -------------------------------------------------------------------------
def convergence():
    import jax
    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import morphojax as mj

    rng = np.random.default_rng(0)
    shape = (21, 23)
    start = mj.State.from_arrays([1 - 0.5 * rng.random(shape), 0.25 * rng.random(shape)])
    model = mj.GrayScott(0.037, 0.06, 0.2, 0.1)
    t_end, dts = 8.0, [1.0, 0.5, 0.25, 0.125, 0.0625]
    every = {"Euler": mj.Euler(), **solvers()}
    rows, fig = [], plt.figure(figsize=(10, 4.2))
    for k, boundary in enumerate(["wrap", "no-flux"]):
        ax = fig.add_subplot(1, 2, k + 1)
        for name, solver in every.items():
            ref = mj.simulate(model, start, int(t_end * 256), 1 / 256, boundary, solver=solver).fields
            err = [float(jnp.abs(mj.simulate(model, start, int(round(t_end / dt)), dt, boundary,
                                             solver=solver).fields - ref).max()) for dt in dts]
            slopes = np.log2(np.array(err[:-1]) / np.array(err[1:]))
            rows.append([boundary, name, solver.order] + [f"{e:.2e}" for e in err] + [f"{slopes[-1]:.2f}"])
            ax.loglog(dts, err, "o-", label=f"{name} (slope {slopes[-1]:.2f})")
        ax.set(title=f"Gray-Scott, {boundary}, t = {t_end:g}, float64", xlabel="dt",
               ylabel="max error vs the same solver at dt = 1/256")
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(RESULTS / "solvers_convergence.png", dpi=110)
    table = markdown_table(["boundary", "solver", "order"] + [f"dt {d:g}" for d in dts] + ["last slope"], rows)
    return ("Convergence", f"Gray-Scott (F 0.037, k 0.06, Du 0.2, Dv 0.1) on a {shape[0]}x{shape[1]} lattice, "
            "nine-point stencil, float64, from a random start to t = 8: the error at each dt against the same "
            "solver at dt = 1/256, limits not binding. Slope = log2 of the error ratio for a halving of dt.\n\n"
            f"![convergence](solvers_convergence.png)\n\n{table}")


# ---- time to solution ------------------------------------------------------------------------
def _time_run(experiment, seed=0):
    """(compile seconds, run seconds, final state) of an experiment: two calls, the second compiled."""
    import jax
    import morphojax as mj
    t0 = time.perf_counter()
    first = mj.run_experiment(experiment, seed=seed, throw=False)
    jax.block_until_ready(first.state.fields)
    t1 = time.perf_counter()
    second = mj.run_experiment(experiment, seed=seed, throw=False)
    jax.block_until_ready(second.state.fields)
    t2 = time.perf_counter()
    return max(0.0, (t1 - t0) - (t2 - t1)), t2 - t1, second.state


def _with_solver(experiment, solver, factor):
    """The experiment with every phase on `solver` at `factor` x its dt, same simulated time."""
    phases = tuple(dataclasses.replace(p, solver=solver, dt=p.dt * factor, steps=max(1, round(p.steps / factor)),
                                       frames=0) for p in experiment.phases)
    return dataclasses.replace(experiment, phases=phases)


def _shown(experiment, state):
    names = list(state.names)
    show = experiment.show if experiment.show in names else names[-1]
    return np.asarray(state.fields[names.index(show)])


FIG4_CANDIDATES = [("ETDRK1", 0.1), ("ETDRK1", 0.2), ("ETDRK2", 0.2), ("ETDRK2", 0.25), ("ETDRK2", 0.3),
                   ("ETDRK4", 0.25), ("ETDRK4", 0.3), ("IMEX1", 0.1), ("IMEX2", 0.2), ("IMEX2", 0.25)]
FIG4_SHAPES = ((50, 50), (150, 150))  # the preset's lattice, and one with ~10x the spots


def _time_simulate(model, state, steps, dt, domain, solver):
    """(compile seconds, run seconds, final state, run CPU seconds) of `simulate`: two calls,
    the second compiled; its CPU time counts all of this process's threads."""
    import jax
    import morphojax as mj
    kw = dict(domain=domain, solver=solver, throw=False, check_dt=False)
    t0 = time.perf_counter()
    jax.block_until_ready(mj.simulate(model, state, steps, dt, **kw).fields)
    t1, c1 = time.perf_counter(), time.process_time()
    out = mj.simulate(model, state, steps, dt, **kw)
    jax.block_until_ready(out.fields)
    t2, c2 = time.perf_counter(), time.process_time()
    return max(0.0, (t1 - t0) - (t2 - t1)), t2 - t1, out, c2 - c1


def fig4_worker():
    import jax
    import morphojax as mj
    phase = mj.preset("fig4-r40").phases[0]
    t_end = phase.steps * phase.dt
    out = {}
    for shape in FIG4_SHAPES:
        state = mj.paper_state(jax.random.key(0), shape)
        c, r, final, cpu = _time_simulate(phase.model, state, phase.steps, phase.dt, phase.domain, mj.Euler())
        ref = mj.describe(np.asarray(final.fields[1]))
        tag = f"{shape[0]}x{shape[1]}"
        out[f"{tag} Euler"] = {"dt": phase.dt, "compile": c, "run": r, "cpu": cpu, "desc": ref.as_dict(),
                               "same": True}
        for name, dt in FIG4_CANDIDATES:
            c, r, final, cpu = _time_simulate(phase.model, state, round(t_end / dt), dt, phase.domain, solvers()[name])
            d = mj.describe(np.asarray(final.fields[1]))
            out[f"{tag} {name} dt {dt:g}"] = {"dt": dt, "compile": c, "run": r, "cpu": cpu,
                                              "desc": d.as_dict(),
                                    "same": same_pattern(ref, d)[0], "why": same_pattern(ref, d)[1]}
    print(json.dumps(out))


def fig4(repeats):
    runs = in_fresh_processes(Path(__file__), ["fig4"], repeats)
    rows = []
    for key in runs[0]:
        euler = median([r[key.split()[0] + " Euler"]["run"] for r in runs])
        run_t = median([r[key]["run"] for r in runs])
        comp = median([r[key]["compile"] for r in runs])
        euler_cpu = median([r[key.split()[0] + " Euler"]["cpu"] for r in runs])
        cpu = median([r[key]["cpu"] for r in runs])
        d = runs[0][key]["desc"]
        rows.append([key, f"{runs[0][key]['dt']:.3g}", f"{run_t:.3f}", f"{comp:.2f}", f"{euler / run_t:.1f}x",
                     f"{cpu:.3f}", f"{euler_cpu / cpu:.1f}x", f"{d['wavelength']:.2f}", d["pattern"], d["spots"],
                     "yes" if all(r[key]["same"] for r in runs) else f"no: {runs[0][key].get('why', '')}"])
    table = markdown_table(["lattice, solver", "dt", "run s (median)", "compile s", "speed-up vs Euler",
                            "CPU s (median)", "in CPU time", "wavelength", "class", "spots", "same pattern"], rows)
    load = os.getloadavg()
    return ("Time to solution: fig4-r40", "`fig4-r40`'s model (Turing r = 40, s = 3, wrap, nine-point) from "
            "`paper_state(key(0))` to t = 100: on the preset's 50x50 lattice and on 150x150. Euler at the "
            "preset's dt 0.003 (its limit is 0.003125). `simulate` timed directly (the second of two calls; "
            f"compilation = first minus second), medians over {repeats} processes, {machine()}. Descriptors "
            "of species b from the first process. The speed-up is the ratio of the wall-clock medians; the CPU "
            "columns are the same second call's CPU time (all of the process's threads), which other work on "
            "a shared machine inflates less (load average "
            f"{load[0]:.1f} / {load[1]:.1f} / {load[2]:.1f} over 1 / 5 / 15 minutes when the last process ended)."
            f"\n\n{table}")


# ---- every preset ----------------------------------------------------------------------------------
LADDER = (4, 16, 64)


def eligible(experiment):
    """None if every phase can run with the transform solvers, else the reason."""
    import jax
    import morphojax as mj
    for p in experiment.phases:
        try:
            shape = tuple(experiment.initial.capacity or experiment.initial.shape)
            fields = jax.ShapeDtypeStruct((p.model.n_species,) + shape, "float32")
            mj.ETDRK(1).check(p.domain, p.model, dynamic=p.growth is not None, sources=p.sources, fields=fields)
        except ValueError as err:
            return str(err).replace("solver=ETDRK(order=1) ", "").replace("solver=ETDRK(order=1): ", "")
    return None


def presets_worker(names):
    """Each preset's row as one JSON line on stdout as soon as it is measured (a long run
    leaves the rows it finished)."""
    import morphojax as mj
    for name in names:
        base = mj.preset(name)
        base = dataclasses.replace(base, phases=tuple(dataclasses.replace(p, frames=0) for p in base.phases))
        wrap = base.phases[-1].domain.boundary == "wrap"
        c, r, state = _time_run(base)
        ref = mj.describe(_shown(base, state), wrap=wrap)
        row = {"Euler": {"factor": 1, "run": r, "compile": c, "desc": ref.as_dict()}}
        for sname, solver in solvers().items():
            best = None
            for factor in LADDER:
                exp = _with_solver(base, solver, factor)
                c, r, state = _time_run(exp)
                d = mj.describe(_shown(exp, state), wrap=wrap)
                ok, why = same_pattern(ref, d)
                if not ok:
                    if best is None:
                        best = {"factor": None, "why": why}
                    break
                best = {"factor": factor, "run": r, "compile": c, "desc": d.as_dict()}
            row[sname] = best
        print(json.dumps({name: row}), flush=True)


def presets(rows_file=None):
    """The table of every eligible preset: measured now, or read from the JSON lines a
    worker wrote (`--presets-from FILE`, for a run started on its own)."""
    import morphojax as mj
    names, skipped = [], []
    for name in sorted(mj.PRESETS):
        try:
            exp = mj.preset(name)
        except ValueError:
            continue  # automata, cells, Potts, figures of several experiments
        reason = eligible(exp)
        (skipped.append((name, reason)) if reason else names.append(name))
    if rows_file is None:
        import os
        import subprocess

        env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(HERE.parent), str(HERE.parent / "tests"), str(HERE)]))
        lines = subprocess.run([sys.executable, str(Path(__file__)), "--worker", "presets", *names],
                               capture_output=True, text=True, env=env, check=False).stdout.splitlines()
    else:
        lines = Path(rows_file).read_text().splitlines()
    result = {}
    for line in lines:
        if line.startswith("{"):
            result.update(json.loads(line))
    rows = []
    for name in [n for n in names if n in result]:
        row = result[name]
        e = row["Euler"]
        cells = [name, f"{e['run']:.2f}", f"{e['desc']['wavelength']:.2f} {e['desc']['pattern']} {e['desc']['spots']}"]
        for sname in solvers():
            s = row[sname]
            if s["factor"] is None:
                cells.append(f"fails at 4x: {s['why']}")
            else:
                cells.append(f"{s['factor']}x: {s['run']:.2f} s ({e['run'] / s['run']:.1f}x)")
        rows.append(cells)
    table = markdown_table(["preset", "Euler s", "Euler: wavelength class spots"] + list(solvers()), rows)
    skipped_text = "\n".join(f"- `{n}`: {why}" for n, why in skipped)
    missing = [n for n in names if n not in result]
    if missing:
        skipped_text += "\n\nEligible but not measured in this run (it was stopped first): " + ", ".join(
            f"`{n}`" for n in missing)
    return ("Every static lattice preset", "Each preset at its own size and simulated time; each solver at "
            f"{', '.join(f'{f}x' for f in LADDER)} the preset's Euler dt, the largest that keeps the same "
            "pattern (ascending, stopping at the first failure), with its compiled run time and the speed-up "
            f"over Euler's. One process, {machine()}, sharing the two cores with the test suite: these single "
            f"timings are rough; the fig4-r40 section has medians.\n\n{table}\n\nNot eligible for the transforms "
            "(IMEX by conjugate gradients runs the hexagonal, mesh and fixed-polarity ones; not timed here):\n"
            f"{skipped_text}")


def write_section(title, body):
    text = REPORT.read_text() if REPORT.exists() else "# Solvers\n"
    block = f"## {title}\n\n{body}\n"
    pattern = re.compile(rf"## {re.escape(title)}\n.*?(?=\n## |\Z)", re.S)
    text = pattern.sub(lambda _: block.rstrip("\n"), text) if pattern.search(text) else text.rstrip("\n") + "\n\n" + block
    REPORT.write_text(text.rstrip("\n") + "\n")


def main():
    if len(sys.argv) > 1 and sys.argv[1] == "--worker":
        job, *rest = sys.argv[2:]
        return fig4_worker() if job == "fig4" else presets_worker(rest)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--convergence", action="store_true")
    ap.add_argument("--fig4", action="store_true")
    ap.add_argument("--presets", action="store_true")
    ap.add_argument("--presets-from", default=None, metavar="FILE",
                    help="build the presets table from the JSON lines of a worker run on its own")
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    if args.convergence:
        write_section(*convergence())
    if args.fig4:
        write_section(*fig4(args.repeats))
    if args.presets or args.presets_from:
        write_section(*presets(args.presets_from))


if __name__ == "__main__":
    main()
