"""Cellular-automaton presets: Young's automaton (Tinson 2022), K species in 3D (Dur 2023)
and life-like rules; `morphojax run young-fig8` or `PRESETS["young-fig8"].run()`.

Every run writes its PNG `out`, `out.npz` with the final cells and a JSON `metadata` entry
holding every parameter (automaton, lattice, initial condition, seed, steps), meshes per
species for 3D lattices and, with `frames=True`, the snapshots (see `_automaton_outputs`).
The same seed gives the same output. Each preset has a `quick` variant that runs in
seconds: smaller lattices, same rules.
"""

from __future__ import annotations

import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from PIL import Image

import morphojax as mj
from .._frames_files import save_frames
from ._automaton_outputs import (automaton_stats, frames_outputs, line_chart, run_automaton, save_cells_npz,
                                 timed_run, xy_chart)
from ._registry import AutomatonPreset, register, registered


def _automaton(name, description, figure):
    """Decorator: register the decorated runner as an automaton preset."""
    return registered(AutomatonPreset, name, description, figure)


# ---- Young's 2D automaton (Tinson 2022) ----------------------------------------------------
YOUNG_R1, YOUNG_R2, YOUNG_W1 = 2.30, 6.01, 1.0
FIG8_W2 = (-0.20, -0.24, -0.28, -0.32, -0.36, -0.40)  # stripes -> spots
FIG8_STEPS = 30  # Tinson 2022: "each simulation is run for 30 time-steps"


@_automaton("young-fig8", "Young's automaton, r1 = 2.30, r2 = 6.01, w1 = 1, w2 from -0.20 to -0.40: stripes to spots",
            "Tinson 2022 Fig. 8 (Young 1984 Fig. 6)")
def _young_fig8(seed, quick, out, frames):
    size = 100 if quick else 200
    # one common denominator so the models stack into one vmapped run
    cas = [mj.YoungCA([(YOUNG_R1, YOUNG_R2, YOUNG_W1, w)], denominator=25) for w in FIG8_W2]
    stacked = jax.tree.map(lambda *x: jnp.stack(x), *cas)
    cells0 = mj.random_cells(jax.random.key(seed), (size, size), 1, mj.YOUNG_P)
    save_every = 5 if frames else None
    t0 = time.perf_counter()
    result = eqx.filter_vmap(lambda m: m.run(cells0, FIG8_STEPS, save_every=save_every, history=True))(stacked)
    jax.block_until_ready(result.cells)
    seconds = time.perf_counter() - t0
    finals = np.asarray(result.cells)
    scale = max(1, 200 // size)
    mj.montage([mj.cells_image(c, 1, scale) for c in finals], len(FIG8_W2),
               col_labels=[f"w2 = {w:g}" for w in FIG8_W2],
               title=f"Young, r1 = {YOUNG_R1}, r2 = {YOUNG_R2}, w1 = 1, p = {mj.YOUNG_P}, t = {FIG8_STEPS}").save(out)
    per = [{"w2": w, **automaton_stats(c, 1)} for w, c in zip(FIG8_W2, finals)]
    metadata = {"automaton": "YoungCA", "params": [ca.to_dict() for ca in cas], "lattice": [size, size],
                "seed": seed, "initial": {"p": mj.YOUNG_P}, "steps": FIG8_STEPS, "w2": list(FIG8_W2), "runs": per}
    files = [str(out), str(save_cells_npz(out, finals, metadata, changes=np.asarray(result.changes)))]
    if frames:
        strip = [mj.cells_image(f, 1, scale) for f in np.asarray(result.frames).reshape(-1, size, size)]
        n_cols = np.asarray(result.frames).shape[1]
        frames_png = out.with_name(out.stem + "_frames.png")
        mj.montage(strip, n_cols, row_labels=[f"w2 = {w:g}" for w in FIG8_W2],
                   col_labels=[f"t = {t}" for t in np.asarray(result.frame_steps)[0]]).save(frames_png)
        frames_npz = out.with_name(out.stem + "_frames.npz")
        save_frames(frames_npz, np.asarray(result.frames), np.asarray(result.frame_steps)[0], frame_axis=1, states=2,
                    runs=[{"w2": w} for w in FIG8_W2])
        files += [str(frames_png), str(frames_npz)]
    return {"steps": FIG8_STEPS, "lattice": [size, size], "runs": per, "seconds_run": round(seconds, 3), "files": files}


def _young_single(w2):
    def runner(seed, quick, out, frames):
        ca = mj.YoungCA([(YOUNG_R1, YOUNG_R2, YOUNG_W1, w2)])
        size = 128 if quick else 256
        return run_automaton(ca, (size, size), p=mj.YOUNG_P, steps=FIG8_STEPS, stop=False, seed=seed, out=out, frames=frames)

    return runner


register(AutomatonPreset("young-stripes", "Young's automaton at w2 = -0.20: labyrinthine stripes",
                         "Tinson 2022 Fig. 8 (left)", _young_single(-0.20)))
register(AutomatonPreset("young-spots", "Young's automaton at w2 = -0.40: isolated spots",
                         "Tinson 2022 Fig. 8 (right)", _young_single(-0.40)))


@_automaton("young-b1", "Tinson's (2022) Python code: Moore boxes Ra = 2, Ri = 5, wa = 1, wi = 0.2, self counted, "
            "20 steps",
            "Tinson 2022 Fig. B1 (evolution over time)")
def _young_b1(seed, quick, out, frames):
    # the code sums the inhibitor over the whole box (self included): WS = Na wa - Ni wi,
    # i.e. weight wa - wi on the inner box and -wi on the ring
    wa, wi = 1.0, 0.2
    ca = mj.YoungCA([(2, 5, wa - wi, -wi)], "box", include_self=True)
    size = 100  # the code's 100 x 100 grid is already quick
    return run_automaton(ca, (size, size), p=mj.YOUNG_P, steps=20, stop=False, seed=seed, out=out, frames=frames,
                         extra={"code_weights": {"wa": wa, "wi": wi}})


def _young_series(cas, labels, columns, title, extra, seed, out, size, steps):
    """Run the models `cas` from one start of Tinson's (2022) code (p = 0.015 differentiated
    cells) for `steps` each, and write the montage of their final states (`columns` to a
    row; each row labelled by the labels of its first and last tile) and the `.npz`."""
    cells0 = mj.random_cells(jax.random.key(seed), (size, size), 1, mj.YOUNG_P)
    finals, seconds = [], 0.0
    for ca in cas:
        result, took = timed_run(ca, cells0, steps)
        finals.append(np.asarray(result.cells))
        seconds += took
    rows = [labels[i:i + columns] for i in range(0, len(labels), columns)]
    tiles = [mj.cells_image(c, 1, max(1, 200 // size)) for c in finals]
    if len(rows) == 1:
        sheet = mj.montage(tiles, columns, col_labels=labels, title=title)
    else:
        sheet = mj.montage(tiles, columns, row_labels=[f"{r[0]} .. {r[-1]}" for r in rows], title=title)
    sheet.save(out)
    per = [{"label": lab, **automaton_stats(c, 1)} for lab, c in zip(labels, finals)]
    metadata = {"automaton": "YoungCA", "params": [ca.to_dict() for ca in cas], "lattice": [size, size],
                "seed": seed, "initial": {"p": mj.YOUNG_P}, "steps": steps, "runs": per, **extra}
    files = [str(out), str(save_cells_npz(out, np.stack(finals), metadata))]
    return {"steps": steps, "lattice": [size, size], "runs": per, "seconds_run": round(seconds, 3), "files": files}


B2_WI = tuple(round(1.05 - 0.05 * i, 2) for i in range(20))  # 1.05 (upper left) to 0.10 (bottom right)


@_automaton("young-b2", "Tinson's (2022) Python code with its inhibitor weight wi from 1.05 to 0.10 (Moore "
            "boxes Ra = 2, Ri = 5, wa = 1, self counted, 20 steps): all off, isolated clusters, small spots, larger "
            "spots, stripes, inverted spots, all on",
            "Tinson 2022 Fig. B2 (varying inhibitor field value)")
def _young_b2(seed, quick, out, frames):
    # the code's WS = Na wa - Ni wi is weight wa - wi on the inner box and -wi on the ring
    # (see young-b1); the first two panels, wi = 1.05 and 1.00, weigh the inner box -0.05
    # and 0: no cell can turn on there (YoungCA's rule on weights: w_act > w_inh)
    cas = [mj.YoungCA([(2, 5, round(1.0 - wi, 2), -wi)], "box", include_self=True, denominator=100) for wi in B2_WI]
    labels = [f"wi = {wi:.2f}" for wi in B2_WI]
    return _young_series(cas, labels, 5, "Tinson 2022 B2: wi from 1.05 (upper left) to 0.10, t = 20, Moore boxes "
                         "Ra 2, Ri 5, wa 1", {"wi": list(B2_WI)}, seed, out, 100, 20)


NEIGHBOURHOOD_NAMES = {"box": "Moore box", "disc": "disc", "diamond": "von Neumann diamond"}


@_automaton("young-neighbourhoods", "Tinson's (2022) automaton (Ra = 2, Ri = 5, wa = 1, wi = 0.2, self counted, "
            "20 steps) with Moore's box, the Euclidean disc and von Neumann's diamond as its neighbourhoods",
            "Tinson 2022 Fig. 1 (Moore and von Neumann neighbourhoods), Fig. B1")
def _young_neighbourhoods(seed, quick, out, frames):
    wa, wi = 1.0, 0.2
    cas = [mj.YoungCA([(2, 5, wa - wi, -wi)], shape, include_self=True) for shape in NEIGHBOURHOOD_NAMES]
    labels = [NEIGHBOURHOOD_NAMES[shape] for shape in NEIGHBOURHOOD_NAMES]
    return _young_series(cas, labels, 3, "Tinson's (2022) code, Ra 2, Ri 5, wa 1, wi 0.2, t = 20",
                         {"neighbourhoods": list(NEIGHBOURHOOD_NAMES)}, seed, out, 100, 20)


# ---- Dur 2023: 3D, K species ------------------------------------------------------------
DUR_K2 = (3.2, 6.0, 1.0, -0.2)  # R_act, R_inh, w_act, w_inh of both species (section 4.2)
DUR_TABLE2 = ((6.0, 10.0, 1.0, -0.3), (4.0, 7.0, 1.0, -0.3), (4.3, 8.0, 1.0, -0.22))  # species 0-2 of Table 2
DUR_TABLE2_W3 = -0.2  # w_{3,inh} is "variable" in Table 2 / Fig. 8; species 3 is otherwise (3.2, 6, 1, .)


@_automaton("dur-fig6", "3D, L = 100, K = 2, both species (3.2, 6, 1, -0.2), run to convergence (< 1% changed); "
            "section 4.2: 42.86% / 42.88% / 14.26% after 20 iterations", "Dur 2023 Fig. 6")
def _dur_fig6(seed, quick, out, frames):
    ca = mj.YoungCA([DUR_K2, DUR_K2])
    size = 40 if quick else 100
    summary = run_automaton(ca, (size,) * 3, p=None, steps=100, stop=True, seed=seed, out=out, frames=frames)
    summary["weighted_volume_difference"] = [round(float(v), 3) for v in np.asarray(mj.weighted_volume_difference(ca))]
    return summary


@_automaton("dur-fig8", "3D, L = 100, K = 4 species of Table 2 (w_3,inh = -0.2), run to convergence",
            "Dur 2023 Fig. 8 / Table 2")
def _dur_fig8(seed, quick, out, frames):
    ca = mj.YoungCA([*DUR_TABLE2, (3.2, 6.0, 1.0, DUR_TABLE2_W3)])
    size = 48 if quick else 100
    summary = run_automaton(ca, (size,) * 3, p=None, steps=100, stop=True, seed=seed, out=out, frames=frames)
    summary["weighted_volume_difference"] = [round(float(v), 3) for v in np.asarray(mj.weighted_volume_difference(ca))]
    return summary


FIG9_W0 = (-0.10, -0.15, -0.20, -0.25, -0.30)
_eps0_series = jax.jit(jax.vmap(lambda cells: mj.order_parameter(cells, 2)[0]))


@_automaton("dur-fig9", "order parameter eps_0 per iteration, K = 2, w_0,inh from -0.10 to -0.30 (identical starts)",
            "Dur 2023 Fig. 9")
def _dur_fig9(seed, quick, out, frames):
    size, steps = (32, 20) if quick else (100, 40)
    cells0 = mj.random_cells(jax.random.key(seed), (size,) * 3, 2)
    series, finals, steps_run = {}, [], []
    t0 = time.perf_counter()
    for w0 in FIG9_W0:
        # one denominator for the whole series (1/20: all its weights are multiples), so
        # the compiled run is reused
        ca = mj.YoungCA([(3.2, 6.0, 1.0, w0), DUR_K2], denominator=20)
        result = ca.run(cells0, steps, save_every=1)
        eps = _eps0_series(result.frames)
        series[f"w0 = {w0:g}"] = [float(v) for v in np.asarray(eps)]
        finals.append(np.asarray(result.cells))
        steps_run.append(int(result.steps))
    seconds = time.perf_counter() - t0
    chart = line_chart(series, title=f"eps_0 per iteration, L = {size}, K = 2")
    mids = mj.montage([mj.cells_image(c[size // 2], 2, max(1, 160 // size)) for c in finals], len(finals),
                      col_labels=[f"w0 = {w:g}" for w in FIG9_W0])
    canvas = Image.new("RGB", (max(chart.width, mids.width), chart.height + mids.height), "white")
    canvas.paste(chart, (0, 0))
    canvas.paste(mids, (0, chart.height))
    canvas.save(out)
    metadata = {"automaton": "YoungCA", "species_1": DUR_K2, "species_0": {"r_act": 3.2, "r_inh": 6.0, "w_act": 1.0},
                "w0_inh": list(FIG9_W0), "lattice": [size] * 3, "seed": seed, "initial": {"p": None},
                "steps": steps, "order_parameter_0": series}
    files = [str(out), str(save_cells_npz(out, np.stack(finals), metadata))]
    return {"steps": steps_run, "lattice": [size] * 3, "order_parameter_0_final": {k: round(v[-1], 4) for k, v in series.items()},
            "seconds_run": round(seconds, 3), "files": files}


FIG7_W0 = (-0.15, -0.18, -0.20, -0.25, -0.30)  # the text names -0.15 and -0.18; the rest span Fig. 9's range


def _dur_series(species_for, values, k, name, seed, quick, out):
    """Dur's (2023) converged-state series (Figs. 7 and 8): for each value, the automaton of
    `species_for(value)` (one denominator for the series, so the compiled run is reused)
    run to convergence from one start, shown as middle slices with each species' share."""
    size = 40 if quick else 100
    cells0 = mj.random_cells(jax.random.key(seed), (size,) * 3, k)
    runs, finals = [], []
    t0 = time.perf_counter()
    for value in values:
        ca = mj.YoungCA(species_for(value), denominator=100)
        result = ca.run(cells0, 100, stop_at_convergence=True)
        finals.append(np.asarray(result.cells))
        runs.append({name: value, "steps": int(result.steps), "converged": bool(result.converged),
                     **automaton_stats(result.cells, k)})
    seconds = time.perf_counter() - t0
    labels = [f"{name[:2]} = {r[name]:g}: " + " / ".join(f"{100 * v:.1f}%" for v in r["volume_fractions"][:k])
              for r in runs]
    mj.montage([mj.cells_image(c[size // 2], k, max(1, 200 // size)) for c in finals], len(finals),
               col_labels=labels, title=f"L = {size}, K = {k}, middle slices; volume of species 0 to {k - 1}").save(out)
    metadata = {"automaton": "YoungCA", "species": [species_for(v) for v in values], name: list(values),
                "lattice": [size] * 3, "seed": seed, "initial": {"p": None}, "runs": runs}
    files = [str(out), str(save_cells_npz(out, np.stack(finals), metadata))]
    return {"lattice": [size] * 3, "runs": runs, "seconds_run": round(seconds, 3), "files": files}


@_automaton("dur-fig7", "3D, L = 100, K = 2, w_0,inh from -0.15 to -0.30 (identical starts), run to convergence, "
            "with each species' share of the volume", "Dur 2023 Fig. 7")
def _dur_fig7(seed, quick, out, frames):
    return _dur_series(lambda w0: [(3.2, 6.0, 1.0, w0), DUR_K2], FIG7_W0, 2, "w0_inh", seed, quick, out)


FIG8_W3 = FIG7_W0  # not printed; section 4.3 names the step from -0.15 to -0.18, as in Fig. 7


@_automaton("dur-fig8-series", "3D, L = 100, K = 4 species of Table 2 with w_3,inh from -0.15 to -0.30 (identical "
            "starts), run to convergence, with each species' share of the volume", "Dur 2023 Fig. 8 / Table 2")
def _dur_fig8_series(seed, quick, out, frames):
    return _dur_series(lambda w3: [*DUR_TABLE2, (3.2, 6.0, 1.0, w3)], FIG8_W3, 4, "w3_inh", seed, quick, out)


# ---- Dur 2023 section 4.5: the order parameter against the weighted volume difference ---
WVD_STEPS = 50  # "after 50 iterations"
WVD_SPECIES = (3.0, 6.0, 1.0, -0.2)  # r_act, r_inh, w_act, w_inh of the species held fixed


def _wvd_series(models, cells_for, steps):
    """Each model run `steps` updates from `cells_for(i)`: the order parameters of its
    species, shape (len(models), K), and the final cells of each run."""
    eps, finals = [], []
    for i, ca in enumerate(models):
        cells = ca.run(cells_for(i), steps).cells
        eps.append(np.asarray(mj.order_parameter(cells, ca.n_species))[:ca.n_species])
        finals.append(np.asarray(cells))
    return np.array(eps), finals


def _wvd_figure(name, figure, vary, values, k, seeded, description):
    """A Dur 2023 section 4.5 preset: the first species' `vary` ("r_act" or "w_act") takes
    `values` (the full series; `quick` takes every tenth), the other species keep
    `WVD_SPECIES`, every run lasts `WVD_STEPS` updates on a 30^3 lattice (20^3 quick) from
    one start (`seeded`) or a different start per value; the picture plots eps_j of every
    species against WVD_0 and, for a radius series, shows one run per neighbourhood (the
    radius enters only through the cells it covers)."""

    def runner(seed, quick, out, frames):
        series = np.asarray(values[::10] if quick else values, float)
        size = 20 if quick else 30
        r_act, r_inh, w_act, w_inh = fixed = WVD_SPECIES
        rows = [(v, r_inh, w_act, w_inh) if vary == "r_act" else (r_act, r_inh, v, w_inh) for v in series]
        # one denominator for the whole series, so runs of one neighbourhood share a compiled loop
        models = [mj.YoungCA([row, *[fixed] * (k - 1)], denominator=1000) for row in rows]
        key = jax.random.key(seed)
        start = mj.random_cells(key, (size,) * 3, k)
        cells_for = (lambda i: start) if seeded else (
            lambda i: mj.random_cells(jax.random.fold_in(key, i), (size,) * 3, k))
        t0 = time.perf_counter()
        eps, finals = _wvd_series(models, cells_for, WVD_STEPS)
        seconds = time.perf_counter() - t0
        wvd0 = np.array([float(mj.weighted_volume_difference(ca)[0]) for ca in models])
        neighbourhood = [ca.neighbour_counts(3)[0].tolist() for ca in models]  # species 0's (disc, ring) cells
        chart = xy_chart({f"eps_{j}": (wvd0, eps[:, j]) for j in range(k)},
                         title=f"{figure}: eps vs WVD_0, L = {size}, K = {k}, {WVD_STEPS} updates",
                         x_label=f"WVD_0 from {wvd0.min():.0f} to {wvd0.max():.0f}", dots=True)
        # the first run of each distinct neighbourhood of species 0 (each step of a radius series)
        firsts = sorted({tuple(nb): i for i, nb in reversed(list(enumerate(neighbourhood)))}.values())
        shown = firsts if vary == "r_act" and len(firsts) <= 12 else []
        canvas = chart
        if shown:
            tiles = mj.montage([mj.cells_image(finals[i][size // 2], k, max(1, 80 // size)) for i in shown],
                               len(shown), col_labels=[f"{wvd0[i]:.0f}" for i in shown])
            canvas = Image.new("RGB", (max(chart.width, tiles.width), chart.height + tiles.height), "white")
            canvas.paste(chart, (0, 0))
            canvas.paste(tiles, (0, chart.height))
        canvas.save(out)
        metadata = {"automaton": "YoungCA", "vary": f"species 0 {vary}", "values": series.tolist(),
                    "fixed_species": fixed, "k": k, "lattice": [size] * 3, "seed": seed, "seeded": seeded,
                    "initial": {"p": None}, "steps": WVD_STEPS}
        files = [str(out), str(save_cells_npz(out, np.stack(finals), metadata, order_parameter=eps,
                                              weighted_volume_difference_0=wvd0,
                                              neighbour_counts_0=np.array(neighbourhood)))]
        levels = len({tuple(np.round(e, 6)) for e in eps})
        return {"lattice": [size] * 3, "runs": len(models), "distinct_neighbourhoods": len(firsts),
                "distinct_order_parameters": levels, "wvd0_range": [round(wvd0.min(), 2), round(wvd0.max(), 2)],
                "seconds_run": round(seconds, 3), "files": files}

    register(AutomatonPreset(name, description, figure, runner))


FIG10_R = np.round(np.arange(2800, 3701) / 1000, 3)  # R_0,act from 2.8 to 3.7 in steps of 0.001
FIG12_W = np.round(np.arange(750, 2051) / 1000, 3)  # w_0,act from 0.75 to 2.05 (step not given: 0.001)
_wvd_figure("dur-fig10", "Dur 2023 Fig. 10", "r_act", FIG10_R, 1, False,
            "eps_0 against WVD_0, K = 1, R_0,act from 2.8 to 3.7 (901 runs), a different random start per run")
_wvd_figure("dur-fig11", "Dur 2023 Fig. 11", "r_act", FIG10_R, 1, True,
            "eps_0 against WVD_0, K = 1, R_0,act from 2.8 to 3.7, one start: a step per neighbourhood")
_wvd_figure("dur-fig12", "Dur 2023 Fig. 12", "w_act", FIG12_W, 1, True,
            "eps_0 against WVD_0, K = 1, R_0,act = 3, w_0,act from 0.75 to 2.05, one start")
_wvd_figure("dur-fig13", "Dur 2023 Fig. 13", "r_act", FIG10_R, 3, True,
            "eps_0, eps_1, eps_2 against WVD_0, K = 3 identical species but R_0,act from 2.8 to 3.7, one start")


# ---- life-like rules ---------------------------------------------------------------------
@_automaton("life-glider", "Conway's B3/S23: a glider moves one cell diagonally every 4 generations",
            "Conway's Game of Life (Gardner 1970)")
def _life_glider(seed, quick, out, frames):
    life = mj.LifeLike("B3/S23")
    size, gens = 16, (16 if quick else 64)  # 64 generations bring it back round the 16-torus
    cells0 = mj.glider((size, size), at=((1 + seed) % size, (1 + seed) % size))
    result = life.run(cells0, gens, save_every=4)
    shown = np.asarray(result.frames)[:9]
    mj.montage([mj.cells_image(1 - f, 1, 8) for f in shown], len(shown),
               col_labels=[f"t={4 * i}" for i in range(len(shown))]).save(out)
    moved = np.array_equal(np.asarray(result.cells), np.roll(np.asarray(cells0), (gens // 4, gens // 4), (0, 1)))
    metadata = {"automaton": "LifeLike", "rule": life.rule, "lattice": [size, size], "seed": seed,
                "initial": "glider", "steps": gens}
    files = [str(out), str(save_cells_npz(out, result.cells, metadata, frames=np.asarray(result.frames)))]
    return {"steps": gens, "rule": life.rule, "glider_moved_diagonally": bool(moved), "files": files}


@_automaton("life-soup", "Conway's B3/S23 from a random 50% soup on a torus", "Conway's Game of Life (Gardner 1970)")
def _life_soup(seed, quick, out, frames):
    life = mj.LifeLike("B3/S23")
    size, gens = (64, 100) if quick else (256, 500)
    cells0 = jax.random.bernoulli(jax.random.key(seed), 0.5, (size, size)).astype(jnp.int8)
    result, seconds = timed_run(life, cells0, gens, save_every=max(1, gens // 10) if frames else None)
    mj.cells_image(1 - np.asarray(result.cells), 1, max(1, 512 // size)).save(out)
    metadata = {"automaton": "LifeLike", "rule": life.rule, "lattice": [size, size], "seed": seed,
                "initial": {"alive_probability": 0.5}, "steps": gens}
    files = [str(out), str(save_cells_npz(out, result.cells, metadata))]
    if frames:
        files += frames_outputs(out, 1 - np.asarray(result.frames), result.frame_steps, 1, max(1, 256 // size))
    return {"steps": gens, "rule": life.rule, "alive": round(float(np.mean(np.asarray(result.cells))), 4),
            "seconds_run": round(seconds, 3), "files": files}
