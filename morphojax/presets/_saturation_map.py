"""Thesis Fig. 7.14 with the areas its caption names: `morphojax run thesis-fig7.14-regions`.

Fig. 7.14 is a parameter map of V, D_U across and U's saturation limit L_U down; its
caption names two areas: "in the darkened area the concentrations fluctuate below the
upper limit, so there is no difference from the standard RD behavior", and "no steady
patterns appear in the blue areas, as the reagents tend to constant concentration". The
preset runs the map of `thesis-fig7.14` (Listing 5.1 on the Moore sum, Du 0 to 0.8 across,
L_U 10 at the top to 3 at the bottom: ranges chosen, the thesis prints none; dt 0.2, 25,000
iterations) and reads both areas from its final state, pixel by pixel, in a window of
`WINDOW` pixels (about a wavelength of the pattern at 128 x 128):

- darkened: no pixel of the window holds U at its own limit (U >= L_U - 1e-3): the limit
  never acts there, the pattern is the standard one;
- blue: V varies by less than `FLAT` over the window: a constant state, no pattern.

The picture is V through the inferno map with the darkened area at a third of its
brightness and the constant area tinted blue. The summary (`regions`) gives the share of the
map in each area, and per band of Du (eight bands across): `limit_acts_below`, the largest
L_U at which U reaches its limit somewhere in the band (the darkened area's lower edge),
`free_max`, U's largest value in the band's top rows (L_U over 9.5, where no limit acts: the
edge should lie near it), and `constant_below`, the largest L_U of the band's constant
pixels (None if none). Reading the final state, not the run's history: "fluctuate below the
limit" is read as "holds no cell at the limit when the run ends".

With seed 0 the limit acts only in a strip of the map: 77% of it is darkened and 13%
constant; in the seven bands with Du over 0.1 the darkened area's edge lies 0.2 to 0.65
above U's unlimited maximum (`free_max`) and 0.3 to 1.05 above the constant area. Under
the clamps, U at L_U with V at 0 is a fixed point (dU/dt = s alpha > 0, dV/dt = -s beta <
0), and below the strip it has taken the whole map. A map from 7 to 3 (tried) leaves about
12% of it to the strip against 10%: the strip is a property of Listing 5.1's rates on a
map more than of the range.
"""

from __future__ import annotations

import json
import time

import numpy as np

import morphojax as mj

from .._files import write_npz
from .._render import colormap_table
from ._registry import AutomatonPreset, lookup, registered

WINDOW = 9  # pixels, the side of the window the areas are read in
FLAT = 0.1  # V's spread over a window below which the state is constant
BANDS = 8  # bands of Du across the map for the summary
FREE_ROWS = 9.5  # L_U above which a row is read as unlimited (`free_max`)


def fig7_14_regions(u, v, limit_u, window: int = WINDOW, flat: float = FLAT) -> tuple[np.ndarray, np.ndarray]:
    """The darkened area (no pixel within the window at U's limit) and the blue one (V's
    spread over the window under `flat`) of a map, as boolean arrays."""
    from scipy.ndimage import maximum_filter, minimum_filter

    at_limit = np.asarray(u) >= np.asarray(limit_u) - 1e-3
    below = ~maximum_filter(at_limit, size=window, mode="nearest")
    v = np.asarray(v, np.float64)
    constant = maximum_filter(v, size=window, mode="nearest") - minimum_filter(v, size=window, mode="nearest") < flat
    return below, constant


def _bands(u, limit_u, below, constant, du) -> list[dict]:
    cols = np.array_split(np.arange(u.shape[1]), BANDS)
    limit_u = np.broadcast_to(limit_u, u.shape)
    out = []
    for c in cols:
        lu, band_u = limit_u[:, c], u[:, c]
        acting = lu[~below[:, c]]
        free = band_u[lu > FREE_ROWS]
        flat_rows = lu[constant[:, c]]
        out.append({"du": [round(float(du[0, c[0]]), 3), round(float(du[0, c[-1]]), 3)],
                    "limit_acts_below": round(float(acting.max()), 2) if acting.size else None,
                    "free_max": round(float(free.max()), 2) if free.size else None,
                    "constant_below": round(float(flat_rows.max()), 2) if flat_rows.size else None})
    return out


def _picture(v, below, constant, scale: int):
    from PIL import Image

    table = colormap_table("inferno").astype(np.float64)
    v = np.asarray(v, np.float64)
    index = np.clip(((v - v.min()) / max(float(np.ptp(v)), 1e-12) * 255).round(), 0, 255).astype(int)
    rgb = table[index]
    rgb[below] *= 1 / 3
    rgb[constant] = 0.45 * rgb[constant] + 0.55 * np.array([40.0, 90.0, 230.0])
    image = Image.fromarray(rgb.round().astype(np.uint8))
    return image.resize((image.width * scale, image.height * scale), Image.NEAREST)


@registered(AutomatonPreset, "thesis-fig7.14-regions", "Fig. 7.14's map (Du 0 to 0.8 across, U's limit 10 to 3 down) "
            "with the caption's areas read from the run: darkened where U never reaches its limit, blue where the "
            "state is constant", "thesis Fig. 7.14 (with its darkened and blue areas)")
def _fig7_14_regions(seed, quick, out, frames):
    """`thesis-fig7.14`'s run (quick: its 48 x 48 map), then the areas of its caption."""
    experiment = lookup("thesis-fig7.14").experiment(quick)
    model = experiment.phases[-1].model
    t0 = time.perf_counter()
    result = mj.run_experiment(experiment, seed=seed, progress=True)
    seconds = time.perf_counter() - t0
    u, v = (np.asarray(result.state.array(name), np.float64) for name in ("a", "b"))
    limit_u = np.broadcast_to(np.asarray(model.upper, np.float64)[0], u.shape)
    du = np.broadcast_to(np.asarray(model.da, np.float64), u.shape)
    below, constant = fig7_14_regions(u, v, limit_u)
    scale = max(1, 256 // u.shape[0])
    mj.montage([_picture(v, np.zeros_like(below), np.zeros_like(constant), scale), _picture(v, below, constant, scale)],
               2, col_labels=["V", "darkened: U below its limit; blue: constant"],
               title="thesis Fig. 7.14: Du 0 to 0.8 across, L_U 10 (top) to 3 (bottom)").save(out)
    # written whole or not at all, with the version and format number (`write_npz`), as every result file
    metadata = {"kind": "saturation-map", "preset": "thesis-fig7.14-regions", "seed": seed,
                "steps": experiment.phases[-1].steps, "experiment": experiment.to_dict()}
    npz = write_npz(out.with_suffix(".npz"), u=u.astype(np.float32), v=v.astype(np.float32), below=below,
                    constant=constant, limit_u=limit_u.astype(np.float32), du=du.astype(np.float32),
                    metadata=json.dumps(metadata))
    regions = {"darkened": round(float(below.mean()), 3), "constant": round(float(constant.mean()), 3),
               "over_limit": int(np.sum(u > limit_u + 1e-4)), "bands": _bands(u, limit_u, below, constant, du)}
    return {"steps": experiment.phases[-1].steps, "shape": list(u.shape), "regions": regions,
            "seconds_run": round(seconds, 3), "files": [str(out), str(npz)]}


__all__ = ["fig7_14_regions"]
