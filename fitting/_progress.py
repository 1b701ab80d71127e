"""The fit's progress bar: the stage, the best loss so far (not the last evaluation), a total.

The first evaluation compiles the simulator, which takes a while before any loss arrives;
the bar says so until then. The total is an estimate (the design's evaluations are known,
the local searches' are at most their budget)."""

from __future__ import annotations

import math


class Progress:
    """A tqdm bar (tqdm.auto: a widget in notebooks) updated once per evaluation."""

    def __init__(self, label: str, total: int):
        from tqdm.auto import tqdm

        self.best = math.inf
        self.bar = tqdm(desc=f"{label}: compiling the first evaluation", total=max(int(total), 1), unit="eval",
                        leave=True)
        self.label = label
        self.stage = None

    def update(self, stage: str, loss: float) -> None:
        """One evaluation of `stage` with `loss`."""
        if stage != self.stage:
            self.stage = stage
            self.bar.set_description(f"{self.label}: {stage}")
        if loss < self.best:
            self.best = loss
        if self.bar.n >= self.bar.total:  # the estimate was short: grow it
            self.bar.total = self.bar.n + 1
        self.bar.update(1)
        self.bar.set_postfix_str(f"best loss {self.best:.4g}")

    def close(self) -> None:
        self.bar.close()
