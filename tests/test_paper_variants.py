"""The papers' last figures and variants as presets (issue 38): thesis Figs. 5.3 and 5.6-5.9
(Listing 5.1's parameter study), paper 003's Appendix B2 and its neighbourhoods, paper
004's own grid setting. Each is checked against the rule it states: an independent NumPy
port of paper 003's code, the paper's printed kernel, the stability limit the thesis's
time steps keep."""

from __future__ import annotations

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import morphojax as mj
from morphojax.domains import laplacian, max_stable_dt
from morphojax.presets._lundelius import SIMS_SCALE, seeded_squares
from morphojax.presets._parameters import FIG5_8_RANGE

PAPER_004_KERNEL = np.array([[0.05, 0.2, 0.05], [0.2, -1.0, 0.2], [0.05, 0.2, 0.05]])


def paper_003_code(grid, steps, wa, wi, ra=2, ri=5):
    """Paper 003's appendix A code, vectorised with np.roll: 1 = active; Na and Ni count the
    active cells of the (2 ra + 1) and (2 ri + 1) boxes around each cell, itself included,
    WS = Na wa - Ni wi; WS > 0 turns a cell on, WS < 0 off, 0 keeps it. Weights compared
    exactly in hundredths."""
    a, i = round(wa * 100), round(wi * 100)
    grid = np.asarray(grid, np.int64)
    for _ in range(steps):
        na = sum(np.roll(grid, (dy, dx), (0, 1)) for dy in range(-ra, ra + 1) for dx in range(-ra, ra + 1))
        ni = sum(np.roll(grid, (dy, dx), (0, 1)) for dy in range(-ri, ri + 1) for dx in range(-ri, ri + 1))
        ws = na * a - ni * i
        grid = np.where(ws > 0, 1, np.where(ws < 0, 0, grid))
    return grid


def test_young_b2_is_paper_003s_code_for_every_weight(tmp_path):
    summary = mj.PRESETS["young-b2"].run(seed=2, quick=True, out=tmp_path / "b2.png")
    with np.load(tmp_path / "b2.npz") as data:
        finals, meta = data["cells"], json.loads(str(data["metadata"]))
    # the appendix's 20 panels, 1.05 (upper left) to 0.10 in steps of 0.05
    assert meta["wi"] == [round(1.05 - 0.05 * i, 2) for i in range(20)] and len(summary["runs"]) == 20
    start = 1 - np.asarray(mj.random_cells(jax.random.key(2), (100, 100), 1, mj.YOUNG_P))  # the code's 1 = active
    for wi, final in zip(meta["wi"], finals):
        np.testing.assert_array_equal(1 - final, paper_003_code(start, 20, 1.0, wi), err_msg=f"wi = {wi}")
    active = [r["volume_fractions"][0] for r in summary["runs"]]
    assert active[2] < 0.1 and active[-1] > 0.9  # spots at a strong inhibitor, nearly all on at a weak one
    # wi >= wa: WS = Na (wa - wi) - (Ni - Na) wi is never > 0. At 1.05 every cell with an active
    # cell in its 11 x 11 box (itself included) turns off: all off after one step. At 1.00 only
    # the start's cells with no other active cell in their ring (the 11 x 11 box less the
    # 5 x 5) stay, and nothing turns on
    assert not (1 - finals[0]).any()
    box = lambda r: sum(np.roll(start, (dy, dx), (0, 1)) for dy in range(-r, r + 1) for dx in range(-r, r + 1))
    alone = start * (box(5) - box(2) == 0)
    assert 0 < alone.sum() < start.sum()
    np.testing.assert_array_equal(1 - finals[1], alone)


def test_young_neighbourhoods_differ_only_in_the_shape(tmp_path):
    mj.PRESETS["young-neighbourhoods"].run(seed=0, quick=True, out=tmp_path / "n.png")
    with np.load(tmp_path / "n.npz") as data:
        finals, meta = data["cells"], json.loads(str(data["metadata"]))
    assert meta["neighbourhoods"] == ["box", "disc", "diamond"]
    assert [p["neighbourhood"] for p in meta["params"]] == meta["neighbourhoods"]
    assert len({f.tobytes() for f in finals}) == 3
    # von Neumann's diamond of radius 2 has 13 cells (self included), 5 x 5 box 25
    counts = [mj.YoungCA([(2, 5, 0.8, -0.2)], shape, include_self=True).neighbour_counts(2)[0].tolist()
              for shape in ("box", "diamond")]
    assert counts[0][0] == 25 and counts[1][0] == 13
    assert counts[1][1] == 2 * 5 * 6 + 1 - 13  # the diamond of radius 5 (61 cells) less the inner one


def test_lundelius_kernel_and_start():
    exp = mj.preset("lundelius-fig3", quick=True)
    seed, run = exp.phases
    # the paper's kernel is SIMS_SCALE times the lattice's stencil: its response to one unit
    impulse = jnp.zeros((7, 7)).at[3, 3].set(1.0)
    assert run.domain == mj.Lattice("nine-point", "wrap")
    response = np.asarray(laplacian(impulse, "wrap", "nine-point"))
    np.testing.assert_allclose(SIMS_SCALE * response[2:5, 2:5], PAPER_004_KERNEL, atol=1e-6)
    assert np.count_nonzero(response) == 9
    assert run.model.du == SIMS_SCALE * 1.0 and run.model.dv == SIMS_SCALE * 0.5
    state = mj.run_experiment(exp.__class__(exp.name, exp.initial, (seed,)), seed=0).state
    b = seeded_squares(exp.initial.shape[0])
    np.testing.assert_array_equal(np.asarray(state.array("v")), b)
    np.testing.assert_array_equal(np.asarray(state.array("u")), np.ones_like(b))


def test_lundelius_umbrella_mesh_keeps_sims_rates_and_forms_a_pattern():
    """Paper 004 on a mesh with its equally weighted Laplacian: Sims's rates unscaled (his
    kernel is also a mean of the neighbours less the centre), dt 1 within the umbrella
    operator's limit, an icosphere whose edges are about 1 (the seeded discs' unit), and a
    quick run that stays finite and forms a pattern from the discs."""
    exp = mj.preset("lundelius-fig4-umbrella", quick=True)
    (run,) = exp.phases
    mesh = run.domain
    assert isinstance(mesh, mj.Mesh) and mesh.operator == "umbrella"
    assert (float(run.model.du), float(run.model.dv)) == (1.0, 0.5) and run.dt == 1.0
    assert run.dt <= mesh.max_stable_dt(1.0) and 1.4 < mesh.rho < 1.6
    v = np.asarray(mesh.vertices, np.float64)
    edges = np.linalg.norm(v[mesh.faces[:, 0]] - v[mesh.faces[:, 1]], axis=1)
    assert 0.8 < edges.mean() < 1.2
    b = mj.run_experiment(exp, seed=0).state.array("v")
    assert np.isfinite(b).all() and 0.0 <= b.min() and b.max() < 1.0
    assert 0.2 < (b > 0.1).mean() < 0.8  # spread over the sphere from 12 discs, not uniform
    assert mj.PRESETS["lundelius-fig4-umbrella"].experiment().phases[0].domain.n_vertices == 10242


def test_listing_5_1_series_keep_the_thesis_time_steps():
    """Figs. 5.6 and 5.9 lower dt where the rates are large (0.8 and 0.6; 0.4 and 0.2), as the
    thesis does, and every member keeps the eight-neighbour sum's limit; Fig. 5.8's map
    ramps Du from 0 in the first column to 0.8 in the last."""
    for figure in ("thesis-fig5.3", "thesis-fig5.6", "thesis-fig5.7", "thesis-fig5.9"):
        for member in mj.PRESETS[figure].members:
            phase = mj.preset(member).phases[-1]
            rate = max(float(np.max(phase.model.da)), float(np.max(phase.model.db)))
            assert phase.dt <= max_stable_dt(rate, "moore"), member
            assert (phase.dt == 1.0) == (rate * 12 <= 2.0), member
    assert [mj.preset(m).phases[0].dt for m in mj.PRESETS["thesis-fig5.9"].members] == [1, 1, 1, 1, 0.4, 0.2]
    phase = mj.preset("thesis-fig5.8", quick=True).phases[0]
    da = np.asarray(phase.model.da)
    np.testing.assert_allclose(da[0], np.linspace(*FIG5_8_RANGE, da.shape[1]), rtol=1e-6)
    assert np.all(da == da[:1]) and phase.dt <= max_stable_dt(FIG5_8_RANGE[1], "moore")


def test_fig5_4_is_listing_5_1_with_five_seeds(tmp_path):
    """Thesis Fig. 5.4: Listing 5.1 on V with the seeds 1 to 5; each panel is the run of
    `thesis-fig5.3-v` (Listing 5.1's preset) with that seed, and the five differ."""
    from PIL import Image

    out = tmp_path / "fig5.4.png"
    summary = mj.PRESETS["thesis-fig5.4"].run(seed=0, quick=True, out=out)
    assert summary["seeds"] == [1, 2, 3, 4, 5] and mj.PRESETS["thesis-fig5.4"].figure == "thesis Fig. 5.4"
    with np.load(out.with_suffix(".npz")) as data:
        v, seeds = data["v"], data["seeds"].tolist()
        meta = json.loads(str(data["metadata"]))
    assert seeds == [1, 2, 3, 4, 5] and meta["member"] == "thesis-fig5.3-v" and v.shape == (5, 32, 32)
    for panel, seed in zip(v, seeds):
        alone = mj.run_experiment(mj.preset("thesis-fig5.3-v", quick=True), seed=seed).state.array("b")
        np.testing.assert_array_equal(panel, np.asarray(alone, np.float32))
    for i in range(5):
        for j in range(i + 1, 5):
            assert np.abs(v[i] - v[j]).max() > 1.0, (seeds[i], seeds[j])  # different patterns, not noise
    assert Image.open(out).width > 5 * 32 * (160 // 32)  # five panels side by side


def test_parameter_maps_ramp_their_parameters_within_the_limit():
    """Figs. 5.5 and 7.14: each map ramps its parameters linearly along its axes (x across
    the columns, y down the rows) and steps within the eight-neighbour sum's limit for its
    fastest rate."""
    from morphojax.presets._parameters import MAPS

    for name, (_, x, y, _) in MAPS.items():
        phase = mj.preset(name, quick=True).phases[0]
        params = phase.model.parameters()
        for axis, spec in (("x", x), ("y", y)):
            if spec is None:
                continue
            values = np.asarray(params[spec[0]])
            line = values[0] if axis == "x" else values[:, 0]
            np.testing.assert_allclose(line, np.linspace(spec[1], spec[2], line.size), rtol=1e-6, err_msg=name)
        rate = max(float(np.max(params["da"])), float(np.max(params["db"])))
        assert phase.dt <= max_stable_dt(rate, "moore") < phase.dt + 0.05 or phase.dt == 1.0, name


def test_the_seed_audit_counts_its_rows_and_names_registered_presets():
    """docs/audit.md: one row per figure with one of four statuses; its counts table agrees
    with the rows, and every preset a row names (a backticked name with a hyphen and no
    wildcard) is registered."""
    import re
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "docs" / "audit.md").read_text(encoding="utf-8")
    sections = re.split(r"^## ", text, flags=re.M)[1:]
    statuses = ("present", "partial", "decided otherwise", "missing")
    counted, stated = {}, {}
    for section in sections:
        title, lines = section.splitlines()[0], section.splitlines()
        rows = [line.split("|")[1:-1] for line in lines if line.startswith("| ") and not line.startswith("| figure")]
        if title == "Counts":
            stated = {r[0].strip(): [int(c) for c in r[1:]] for r in rows[1:]}
            continue
        status = [r[1].strip() for r in rows]
        assert set(status) <= set(statuses), (title, set(status) - set(statuses))
        counted[title.split(",")[0]] = [len(rows)] + [status.count(s) for s in statuses]
        for r in rows:
            for name in re.findall(r"`([a-z0-9.\-]+)`", r[2]):
                if "-" in name:
                    assert name in mj.PRESETS, (title, name)
    assert stated.pop("all") == [sum(c) for c in zip(*counted.values())]
    assert stated == counted


def test_dur_fig8_series_species_1_takes_room_when_species_3_weakens(tmp_path):
    """Paper 002 section 4.3 on Fig. 8: changing species 3 has little effect on the others,
    except species 1 in the step from -0.15 to -0.18; species 3 itself shrinks as its
    inhibitor strengthens."""
    fig8 = mj.PRESETS["dur-fig8-series"].run(seed=0, quick=True, out=tmp_path / "f8.png")
    share = {r["w3_inh"]: r["volume_fractions"] for r in fig8["runs"]}
    assert all(r["converged"] for r in fig8["runs"]) and len(share) == 5
    assert share[-0.18][1] > share[-0.15][1] + 0.05
    species_3 = [share[w][3] for w in sorted(share, reverse=True)]
    assert all(a > b for a, b in zip(species_3, species_3[1:]))
    assert max(abs(share[w][0] - share[-0.2][0]) for w in share) < 0.05  # species 0 barely moves


def cubic_oracle(model, lo, hi):
    """The roots and extrema of a model's reaction from NumPy alone: the cubic through eight
    direct evaluations of it (np.polyfit), np.roots of it and of its derivative."""
    c = np.linspace(lo, hi, 8)
    y = np.array([float(model.reaction(jnp.array([v]))[0]) for v in c])
    coeffs = np.polyfit(c, y, 3)
    assert np.allclose(np.polyval(coeffs, c), y, atol=1e-5 * np.abs(y).max())  # it is a cubic
    roots = np.sort(np.roots(coeffs).real)
    extrema = np.sort(np.roots(np.polyder(coeffs)).real)
    return roots, extrema, np.polyval(coeffs, extrema), np.polyval(np.polyder(coeffs, 2), extrema)


@pytest.mark.parametrize("t, w", [(1.0, 1.0), (5.0, 2.0), (-0.5, 0.3)])
def test_reinforcement_term_marks_are_the_models(t, w):
    from morphojax.presets._reinforcement_term import term_marks

    model = mj.Reinforcement(threshold=t, width=w)
    lo, hi = t - 1.25 * w, t + 1.25 * w
    marks = term_marks(model, lo, hi)
    roots, extrema, rates, curvature = cubic_oracle(model, lo, hi)
    np.testing.assert_allclose([r["at"] for r in marks["root"]], roots, atol=1e-4 * w)
    assert [r["attracts"] for r in marks["root"]] == [True, False, True]  # eq. 6: t repels, t -+ w attract
    (low,), (high,) = marks["minimum"], marks["maximum"]
    assert curvature[0] > 0 > curvature[1]  # the oracle's first extremum is the minimum
    np.testing.assert_allclose([low["at"], high["at"]], extrema, atol=1e-4 * w)
    np.testing.assert_allclose([low["rate"], high["rate"]], rates, rtol=1e-4)
    # the section's statements: roots t - w, t, t + w; -w and +w at the extrema
    np.testing.assert_allclose(roots, [t - w, t, t + w], atol=1e-4 * w)
    np.testing.assert_allclose(rates, [-w, w], rtol=1e-4)


def test_reinforcement_term_preset_draws_the_marks(tmp_path):
    summary = mj.PRESETS["reinforcement-term"].run(out=tmp_path / "term.png")
    assert (tmp_path / "term.png").exists() and summary["model"]["threshold"] == summary["model"]["width"] == 1.0
    roots, extrema, rates, _ = cubic_oracle(mj.Reinforcement(threshold=1.0, width=1.0), *summary["range"])
    drawn = summary["drawn"]  # read back from the plot's markers
    np.testing.assert_allclose(drawn["root"], np.stack([roots, np.zeros(3)], 1), atol=1e-4)
    np.testing.assert_allclose(drawn["minimum"] + drawn["maximum"], np.stack([extrema, rates], 1), atol=1e-4)
