"""Cellular Potts presets (Tinson 2022, section III.B, Figs. 10-11 and appendix D):
`morphojax run potts-fig10` or `PRESETS["potts-fig11"].run()`.

Every run starts from the paper's blob (100x100, radius 40, cells 5 wide, types drawn with
the seed's key) and runs `Potts.paper003(j_like)` (T 10, V 25, lambda 2, J 16 between
unlike types and with the medium, order 2) for 3,000 MCS with the key fold_in(key(seed), 1).
It writes the PNG `out` (types coloured: medium black, type 1 blue, type 2 green; cell
borders dark), `out.npz` (final `ids` (runs x rows x cols), `types`, `j_like`, and a JSON
`metadata` entry with every parameter, the seed and each run's `type_clusters`
descriptors) and `out.csv` (the descriptor table). `quick`: 40x40, radius 16, 200 MCS.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import time
from pathlib import Path
from typing import ClassVar

import jax
import numpy as np

import morphojax as mj
from .._files import write_npz
from ._registry import AutomatonPreset, register

FIG10_J = tuple(0.5 * k for k in range(1, 37))  # appendix D: J(1,1) = J(2,2) from 0.5 to 18 in steps of 0.5
FIG10_QUICK_J = (0.5, 3.0, 6.0, 9.0, 12.0, 15.0, 18.0)
FIG11_J = (3.0, 15.0)  # Fig. 11: 3 "zebra stripes", 15 "leopard spots"
PAPER_MCS = 3000  # "approximately 3000 Monte Carlo Steps"


@dataclasses.dataclass(frozen=True)
class PottsPreset(AutomatonPreset):
    """A cellular Potts run: `build(seed, quick, out, frames) -> summary dict`, as an
    automaton preset, under its own kind."""

    kind: ClassVar[str] = "potts"


def _size(quick):
    return (40, 16, 200) if quick else (100, 40, PAPER_MCS)


def run_series(j_values, seed, quick, out: Path, title: str, ncols: int, row_labels=None, col_labels=None) -> dict:
    """Tinson's (2022) model at each like-type J from one blob; writes `out`, `out.npz`, `out.csv`."""
    size, radius, mcs = _size(quick)
    key = jax.random.key(seed)
    state = mj.potts_blob((size, size), radius, 5, key=key)
    finals, rows, t0 = [], [], time.perf_counter()
    for j in j_values:
        model = mj.Potts.paper003(j)
        final = model.run(state, mcs, jax.random.fold_in(key, 1))
        finals.append(final)
        rows.append({"j_like": j, **mj.type_clusters(final)})
    seconds = time.perf_counter() - t0
    scale = 3 if len(j_values) > 4 else 4
    labels = None if row_labels or col_labels else [f"J = {j:g}" for j in j_values]
    mj.montage([mj.potts_image(f, scale) for f in finals], ncols, row_labels=row_labels,
               col_labels=col_labels or labels, title=title).save(out)
    model = mj.Potts.paper003(j_values[0])
    metadata = {"kind": "potts", "model": "Potts.paper003", "j_like": list(j_values), "j_unlike": 16.0,
                "j_medium": 16.0, "temperature": float(model.temperature), "target_volume": float(model.target_volume),
                "volume_weight": float(model.volume_weight), "order": model.order, "boundary": model.boundary,
                "lattice": [size, size], "blob": {"radius": radius, "cell_width": 5, "types": [1, 2]},
                "seed": seed, "run_key": "fold_in(key(seed), 1)", "mcs": mcs, "quick": quick, "runs": rows}
    npz = write_npz(out.with_suffix(".npz"), ids=np.stack([np.asarray(f.ids) for f in finals]),
                    types=np.asarray(state.types), j_like=np.asarray(j_values, float), metadata=json.dumps(metadata))
    table = out.with_suffix(".csv")
    with open(table, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    return {"mcs": mcs, "lattice": [size, size], "runs": rows, "seconds_run": round(seconds, 3),
            "files": [str(out), str(npz), str(table)]}


def _fig10(seed, quick, out, frames):
    if quick:
        return run_series(FIG10_QUICK_J, seed, quick, out, "Potts, Tinson 2022 appendix D (quick)", len(FIG10_QUICK_J))
    return run_series(FIG10_J, seed, quick, out, "Potts, Tinson 2022 Fig. 10 / appendix D: like-type J from 0.5 to 18",
                      6, row_labels=[f"J {FIG10_J[6 * r]:g}" for r in range(6)],
                      col_labels=[f"+{0.5 * c:g}" for c in range(6)])


def _fig11(seed, quick, out, frames):
    return run_series(FIG11_J, seed, quick, out, "Potts, Tinson 2022 Fig. 11: J = 3 (stripes), 15 (spots)", 2)


register(PottsPreset("potts-fig10", "cellular Potts model, like-type J from 0.5 to 18 (unlike and medium 16): "
                     "bands of sorted cells at low J, single cells of one type among the other above 16",
                     "Tinson 2022 Fig. 10, appendix D", _fig10))
register(PottsPreset("potts-fig11", "cellular Potts model at like-type J = 3 and J = 15",
                     "Tinson 2022 Fig. 11 (CPM column)", _fig11))


def potts_picture(path: Path, scale: int | None = None):
    """A saved Potts run (`morphojax render`): its lattice, or a montage of a series."""
    from .._checks import check_picture
    from ._preset_files import load_potts

    ids, types, meta = load_potts(path)
    scale = (3 if ids.ndim == 3 and ids.shape[0] > 4 else 4) if scale is None else scale
    stack = ids if ids.ndim == 3 else ids[None]
    check_picture(stack.shape, scale, f"the picture of {path}")
    tiles = [mj.potts_image(mj.PottsState(i, types), scale) for i in stack]
    if len(tiles) == 1:
        return tiles[0]
    j = meta.get("j_like") or [None] * len(tiles)
    return mj.montage(tiles, min(6, len(tiles)), col_labels=None,
                      title="Potts: J = " + ", ".join(f"{v:g}" for v in j if v is not None))
