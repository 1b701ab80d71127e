"""Thesis Fig. 7.14's caption areas (`morphojax/presets/_saturation_map.py`): the darkened
area is where no pixel within the window holds U at its own limit, the blue one where V is
flat over it; on the quick map (48 x 48, a few seconds) the limit acts at the bottom (low
L_U) and not at the top, the constant state sits at the bottom, and no pixel passes its
limit."""

from __future__ import annotations

import numpy as np

import morphojax as mj
from morphojax.presets._saturation_map import fig7_14_regions


def test_areas_are_read_in_a_window():
    u = np.full((20, 20), 2.0)
    limit = np.full((20, 20), 5.0)
    u[10, 10] = 5.0  # one pixel at its limit
    v = np.zeros((20, 20))
    v[:, 12:] = np.linspace(0.0, 3.0, 8)  # a ramp on the right, flat on the left
    below, constant = fig7_14_regions(u, v, limit, window=5, flat=0.1)
    assert not below[8:13, 8:13].any() and below[:8].all() and below[:, :8].all()
    assert constant[:, :9].all() and not constant[:, 11:].any()


def test_quick_map_places_the_areas(tmp_path):
    summary = mj.PRESETS["thesis-fig7.14-regions"].run(seed=0, quick=True, out=tmp_path / "m.png")
    regions = summary["regions"]
    assert regions["over_limit"] == 0 and summary["shape"] == [48, 48]
    with np.load(tmp_path / "m.npz") as data:
        below, constant, limit_u = data["below"], data["constant"], data["limit_u"]
        meta = __import__("json").loads(str(data["metadata"]))
    assert meta["morphojax"] == mj.__version__ and meta["format_version"] >= 1  # as every result file
    assert meta["preset"] == "thesis-fig7.14-regions" and meta["seed"] == 0
    assert limit_u[0, 0] > limit_u[-1, 0]  # L_U falls down the map
    assert below[:12].mean() > 0.8 and below[-12:].mean() < 0.2  # the limit acts at the bottom only
    assert constant[-6:].mean() > 0.5 and constant[:12].mean() < 0.1  # constant under the steady state's U = 4
    edges = [b["limit_acts_below"] for b in regions["bands"]]
    assert all(3.0 <= e <= 10.0 for e in edges)
