"""Observables of a Potts lattice: the same-type clusters that tell spots from stripes."""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from ._state import PottsState


def type_clusters(state: PottsState, connectivity: int = 4) -> dict:
    """Connected regions of sites of one cell type (medium excluded), `connectivity` 4 or 8.

    Returns a dict of plain numbers:
    - `clusters`: the number of same-type regions, over every type;
    - `cells`: cells with at least one site;
    - `cells_per_cluster`: cells / clusters (1 when every cell is surrounded by other types:
      spots of single cells; large when cells of a type merge into bands: stripes);
    - `largest_fraction`: the largest region's sites over all cell sites;
    - `like_contacts`: among pairs of nearest-neighbour sites in two different cells (medium
      excluded), the fraction whose cells have one type (0.5 for random types of equal
      shares; towards 1 as the types sort into bands, below 0.5 as they alternate);
    - `elongation`: sqrt of the ratio of the largest region's principal second moments
      (1 for a disc or a square, large for a band).
    """
    if connectivity not in (4, 8):
        raise ValueError(f"connectivity must be 4 or 8 (got {connectivity!r})")
    ids, types, volumes = state.arrays()
    t = types[ids]
    structure = ndimage.generate_binary_structure(2, 1 if connectivity == 4 else 2)
    clusters, best, best_size = 0, None, 0
    for kind in np.unique(t[t > 0]):
        labels, n = ndimage.label(t == kind, structure)
        clusters += n
        if n:
            sizes = np.bincount(labels.ravel())[1:]
            k = int(np.argmax(sizes))
            if sizes[k] > best_size:
                best_size, best = int(sizes[k]), labels == k + 1
    like = unlike = 0
    for a, b in ((ids[:, :-1], ids[:, 1:]), (ids[:-1], ids[1:])):
        border = (a != b) & (a > 0) & (b > 0)
        same = types[a] == types[b]
        like += int((border & same).sum())
        unlike += int((border & ~same).sum())
    cells = int((volumes[1:] > 0).sum())
    occupied = int((t > 0).sum())
    elongation = 1.0
    if best is not None and best_size > 1:
        rr, cc = np.nonzero(best)
        cov = np.cov(np.stack([rr, cc]).astype(float))
        lo, hi = np.linalg.eigvalsh(cov)
        elongation = float(np.sqrt(hi / max(lo, 1e-12)))
    return {"clusters": int(clusters), "cells": cells,
            "cells_per_cluster": round(cells / clusters, 4) if clusters else 0.0,
            "largest_fraction": round(best_size / occupied, 4) if occupied else 0.0,
            "like_contacts": round(like / (like + unlike), 4) if like + unlike else 0.0,
            "elongation": round(elongation, 4)}
