"""`model="auto"`: screen every family cheaply, fit the best few in full, rank them.

Screening runs each family's global design only (no local search, no intervals) on a lattice
of half the rows and columns (at least 24; wavelengths are in cells, so the statistics stay
comparable), with two seeds; oriented families screen on the full lattice, since a small
torus admits only the few stripe directions and spacings that close around it. The `top`
families first in the screen's order are then fitted in full and the best of those is
returned. While every full fit is rejected (a degenerate coat: grid-scale, uniform, unstable
or off the target's wavelength), the next families the screen did not reject are fitted in
full too, one at a time and `top` more at most: a degenerate coat is the answer only when
none of those draws anything else (on the photo-like suite's report seeds, before this rule,
2 of the first 6 cases returned a rejected coat while a family the screen kept was never
fitted).

The screen orders the families by what they were not fitted to (`screen="heldout"`, the
default): the texture distance of each family's best design point's samples (its seeds'
fields, kept from the design, no second run) to the held-out tile of the target
(`fitting._verdict.heldout_distance`), the measure that ranks the full fits. With
`screen="loss"` it orders them by a penalised synthetic likelihood, the rule before: every
family's `score` is the distance between the target's and the fit's statistics with the
config's fixed per-group noise scales (the same yardstick for every family; each family's
own measured noise would make a noisier family look better), which sums about one unit of
squared noise per statistics group, so it plays the part of -2 log L; the penalty is BIC's
k log(n) with k the number of fitted parameters and n the number of statistics groups:
penalised = score + k log(n). Both are recorded in each screened family's ranking row
(`heldout`, `penalised`). A family whose every design point is off the target's scale
(grid-scale, or more than 20% off its wavelength: it cannot reach it inside its bounds)
screens last, rejected, and says so. `benchmarks/screen_photolike.py` compares the two
rules on the photo-like suite.

The full fits are ranked by how well they predict what they were not fitted to: the
held-out distance of `fitting._verdict` (the fit's samples against the tile of the target
kept apart), with rejected fits (degenerate coats: grid-scale, uniform, unstable, off the
target's wavelength) after every fit that is not. The training loss decided before, and
grid-scale noise from the leopard family beat the only family that draws stripes on a tiger
(its statistics sat nearer noise than regular stripes).

Oriented families (`anisotropic-turing`) apply to oriented targets only: they join the
screen when the target's stripe coherence (`fitting.stripe_angle`, structure tensor, 0 for
an isotropic texture, 1 for straight stripes) is at least ORIENTED_COHERENCE. Isotropic
64x64 Turing fields measure 0.14 and spotted photo crops 0.11-0.27, so the screen pays for
them only where a direction is there to fit; `families=[...]` overrides the choice.

A striped target gets a family that draws stripes in the running: when the target's
coherence reaches STRIPED_COHERENCE, the best-screened oriented family is always fitted in
full (besides the `top`). Whether a fit shows the target's stripes (coherence within
STRIPE_MATCH of the target's, direction within STRIPE_ANGLE) is recorded in each ranking row
(`coherence`, `shows_stripes`); the held-out distance, whose orientation group sees the
stripes' direction, decides the order.

Families have different model structures (species, phases, growth), so they are fitted one
after the other; within a family the design points and seeds are vmapped batches, and the
compiled programs are cached per family and lattice across fits.
"""

from __future__ import annotations

import math

import numpy as np

from ._families import FAMILIES, stripe_angle
from ._fit import fit_one
from ._verdict import off_scale

ORIENTED_COHERENCE = 0.3
STRIPED_COHERENCE = 0.5  # a target this coherent is striped: its fits must show the stripes
STRIPE_MATCH = 0.25  # a fit shows them with coherence at least the target's minus this
STRIPE_ANGLE = math.pi / 8  # and a direction within this of the target's (radians, modulo pi)

# families fitted in full after the screen: on the photo-like suite's tuning seeds the screen
# ranks the right family third in 3 of 8 cases, and fitting three in full returned the right
# family in 6 of 8 (benchmarks/results/fit_photolike-top3-tuning.md); three full fits instead of
# two are half as much again of the full fits' time
TOP = 3


def penalised(score: float, k: int, cfg) -> float:
    """score + k log(number of statistics groups) (see the module docstring)."""
    return float(score) + k * math.log(len(cfg.groups()))


def _names_for(fam, names):
    if names is None:
        return list(fam.fit)
    known = fam.parameters()
    mine = [n for n in names if n.rpartition(":")[2] in known]
    return mine or list(fam.fit)


def _fixed_for(fam, fixed) -> dict:
    """The held parameters (`fixed`, {name: value} or None) that the family has."""
    known = fam.parameters()
    return {k: v for k, v in (fixed or {}).items() if k.rpartition(":")[2] in known}


def families_for(field, families=None) -> list:
    """The families `auto` screens for a target field: `families` when given (checked),
    else every isotropic family, and the oriented ones when the field's stripe coherence
    reaches ORIENTED_COHERENCE."""
    if families is not None:
        for f in families:
            if f not in FAMILIES:
                raise ValueError(f"unknown model family {f!r} in families; allowed: {', '.join(FAMILIES)}")
        return list(families)
    oriented = stripe_angle(field)[1] >= ORIENTED_COHERENCE
    return [f for f, fam in FAMILIES.items() if oriented or not fam.oriented]


def shows_stripes(field, target_stripes) -> tuple[bool, float]:
    """(whether a fit's sample shows the target's stripes, the sample's coherence);
    `target_stripes` is the target's (direction, coherence). Any sample passes for a target
    below STRIPED_COHERENCE."""
    direction, coherence = stripe_angle(field)
    if target_stripes[1] < STRIPED_COHERENCE:
        return True, coherence
    off = abs((direction - target_stripes[0] + math.pi / 2) % math.pi - math.pi / 2)
    return bool(coherence >= target_stripes[1] - STRIPE_MATCH and off <= STRIPE_ANGLE), coherence


SCREEN_RULES = ("heldout", "loss")


def screen(target, names, families, options, score=None, rule: str = "heldout", progress=None) -> list:
    """Every family's global design on the screening lattice (module docstring); one row per
    family, ordered: rejected families last, then by `rule`: "heldout", the held-out distance
    of the design's best point's samples (`score(samples)`, `fitting._verdict.heldout_distance`)
    or "loss", the penalised training loss."""
    if rule not in SCREEN_RULES:
        raise ValueError(f"screen rule must be one of {', '.join(SCREEN_RULES)} (got {rule!r})")
    if rule == "heldout" and score is None:
        raise ValueError("screen rule 'heldout' needs the held-out scorer")
    cfg = options["stats"]
    rows, cols = options["shape"]
    half = (max(24, rows // 2), max(24, cols // 2))
    screened = []
    for f in families:
        fam = FAMILIES[f]
        mine = _names_for(fam, names)
        # oriented families screen on the full lattice: a small torus admits only a few
        # stripe directions and spacings (those that close around it), which ranked the
        # zebra's stripes below labyrinths on 32x32
        opts = {**options, "shape": tuple(options["shape"]) if fam.oriented else half, "seeds": 2, "rounds": 0,
                "keep": 1, "max_steps": 0, "intervals": False, "n_design": 6 * len(mine),
                "fixed": _fixed_for(fam, options.get("fixed"))}
        res = fit_one(target, f, mine, progress=progress, stage_prefix="screen ", screen_only=True, **opts)
        lam, lam_t = res.config["wavelength"], res.config["target_wavelength"]
        samples = res.fields.get("samples")
        heldout = float(score(samples)) if score is not None and samples is not None else math.nan
        screened.append({"family": f, "score": res.score, "penalised": penalised(res.score, len(mine), cfg),
                         "heldout": heldout, "params": res.params, "k": len(mine), "stage": "screen",
                         "seconds": res.timings["total"],
                         "rejected": f"wavelength {lam:.1f} cells at its best design point against the "
                                     f"target's {lam_t:.1f}: off the target's scale inside its bounds"
                         if off_scale(lam, lam_t) else None})
    # a family whose every design point is off the target's scale screens last
    key = "heldout" if rule == "heldout" else "penalised"
    screened.sort(key=lambda r: (r["rejected"] is not None, r[key] if np.isfinite(r[key]) else math.inf))
    return screened


def fit_auto(target, names, *, families=None, top=TOP, progress, assess, score=None, screen_rule="heldout",
             **options):
    """Screen, fit the best `top` in full, rank; see the module docstring. `assess` sets a
    full fit's held-out report and rejection, `score` gives samples' held-out distance
    (`fitting._pipeline`)."""
    chosen = families_for(target.field, families)
    if int(top) < 1:
        raise ValueError(f"top must be an integer >= 1 (got {top!r})")
    cfg = options["stats"]
    screened = screen(target, names, chosen, options, score, screen_rule, progress)
    stripes = stripe_angle(target.field)
    to_fit = screened[: int(top)]
    oriented = [r for r in screened if FAMILIES[r["family"]].oriented]
    if stripes[1] >= STRIPED_COHERENCE and oriented and oriented[0] not in to_fit:
        to_fit = to_fit + oriented[:1]  # a striped target: its best oriented family too

    def fit_full(row):
        fam = FAMILIES[row["family"]]
        mine = _names_for(fam, names)
        opts = {**options, "fixed": _fixed_for(fam, options.get("fixed"))}
        res = assess(fit_one(target, row["family"], mine, progress=progress, **opts))
        return (*shows_stripes(res.sample, stripes), penalised(res.score, len(mine), cfg), res)

    full = [fit_full(row) for row in to_fit]
    # while every full fit is rejected (a degenerate coat), the next families the screen did
    # not reject are fitted in full too, `top` more at most: a degenerate coat is returned only
    # when no family the screen kept draws anything else
    waiting = [r for r in screened if r not in to_fit and r["rejected"] is None][: int(top)]
    while waiting and all(item[-1].rejected is not None for item in full):
        full.append(fit_full(waiting.pop(0)))
    # rejected fits last, then by the held-out distance
    full.sort(key=lambda item: (item[-1].rejected is not None, item[-1].heldout["distance"]))
    ranking = [{"family": r.family, "loss": r.score, "penalised": p, "k": len(r.params), "params": r.params,
                "fit_loss": r.loss, "stage": "full", "seconds": r.timings["total"], "coherence": c,
                "shows_stripes": ok, "heldout": r.heldout["distance"], "convincing": r.convincing,
                "rejected": r.rejected} for ok, c, p, r in full]
    done = {r["family"] for r in ranking}
    ranking += [{"family": r["family"], "loss": r["score"], "penalised": r["penalised"], "k": r["k"],
                 "params": r["params"], "stage": "screen", "seconds": r["seconds"], "rejected": r["rejected"],
                 "heldout": r["heldout"]}
                for r in screened if r["family"] not in done]
    best = full[0][-1]
    best.ranking = ranking
    best.config["screen"] = {"rule": screen_rule, "order": [
        {k: r[k] for k in ("family", "heldout", "penalised", "rejected")} for r in screened]}
    best.timings["auto_screen"] = float(sum(r["seconds"] for r in screened))
    best.timings["auto_fits"] = float(sum(item[-1].timings["total"] for item in full))
    return best
