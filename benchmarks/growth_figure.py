"""The leopard paper's Fig. 3: where random matrix expansion puts the new cells.

A 100x100 lattice of original cells (dark) is expanded to 200x200; lighter colours are cells
added later (`Growth.birth_times`). Columns: shuffled indices, uniform, clipped normal,
triangular (the paper's four) and the leopard's profile that halves the division
probability of the middle rows. The bottom row shows the histogram of 200,000 dividing
indices drawn on a 100-cell line, with the exact law (`Growth.law`) over it.

    python benchmarks/growth_figure.py      # writes benchmarks/results/growth_distributions.png
"""

from __future__ import annotations

from pathlib import Path

import jax
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import morphojax as mj  # noqa: E402
from morphojax.presets import leopard_row_weights  # noqa: E402

HERE = Path(__file__).resolve().parent


def main():
    cases = [("shuffle", mj.Growth(1.0, "shuffle")), ("uniform", mj.Growth(1.0, "uniform")),
             ("clipped normal", mj.Growth(1.0, "normal")), ("triangular", mj.Growth(1.0, "triangular")),
             ("uniform, leopard rows", mj.Growth(1.0, row_weights=leopard_row_weights()))]
    fig, axes = plt.subplots(2, len(cases), figsize=(3.2 * len(cases), 6.4), gridspec_kw={"height_ratios": [3, 2]})
    n = 100
    for j, (name, growth) in enumerate(cases):
        birth = np.asarray(growth.birth_times((n, n), n, jax.random.key(j)))
        axes[0, j].imshow(birth, cmap="inferno", vmin=0, vmax=n, interpolation="nearest")
        axes[0, j].set_title(name)
        axes[0, j].set_axis_off()
        idx = np.asarray(growth.draw(jax.random.key(100 + j), n, 200_000, n, growth.row_weights))
        axes[1, j].hist(idx, bins=np.arange(n + 1) - 0.5, density=True, color="0.6")
        axes[1, j].plot(np.arange(n), growth.law(n, growth.row_weights), color="C3", lw=1.2, label="law")
        axes[1, j].set_xlabel("dividing row index")
        axes[1, j].set_ylim(0, None)
    axes[1, 0].set_ylabel("frequency")
    axes[1, 0].legend(frameon=False)
    fig.suptitle("100x100 grown to 200x200: darker cells are older (expansion number)")
    fig.tight_layout()
    out = HERE / "results" / "growth_distributions.png"
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=90)
    print(out)


if __name__ == "__main__":
    main()
