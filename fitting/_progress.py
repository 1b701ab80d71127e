"""The fit's progress: a bar in terminals and notebooks, plain log lines elsewhere.

The bar (`Progress`) shows the stage, the best loss so far (not the last evaluation) and a
total; the first evaluation compiles the simulator, which takes a while before any loss
arrives, and the bar says so until then. The total is an estimate (the design's evaluations
are known, the local searches' are at most their budget). Where stderr is not a terminal (a
log file, a batch job), `LogProgress` writes one line per finished stage with its best loss
and its seconds instead."""

from __future__ import annotations

import math
import sys
import time

MODES = ("bar", "log")


def make_progress(mode: str | None, label: str, total: int):
    """The reporter for a progress `mode`: "bar", "log" or None (silent)."""
    if mode is None:
        return None
    if mode not in MODES:
        raise ValueError(f"progress mode must be one of {', '.join(MODES)} or None (got {mode!r})")
    return Progress(label, total) if mode == "bar" else LogProgress(label)


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


class LogProgress:
    """One line on stderr per finished stage: label, stage, evaluations, best loss, seconds."""

    def __init__(self, label: str, stream=None):
        self.label = label
        self.stream = stream
        self.stage = None
        self.best = math.inf
        self.count = 0
        self.start = time.perf_counter()
        self.since = self.start

    def update(self, stage: str, loss: float) -> None:
        """One evaluation of `stage` with `loss`; a new stage ends the last one's line."""
        if stage != self.stage:
            self._line()
            self.stage, self.count, self.since = stage, 0, time.perf_counter()
        self.count += 1
        if loss < self.best:
            self.best = loss

    def _line(self) -> None:
        if self.stage is None:
            return
        seconds = time.perf_counter() - self.since
        print(f"fit {self.label}: {self.stage} done, {self.count} evaluations, best loss {self.best:.4g}, "
              f"{seconds:.1f} s", file=self.stream or sys.stderr, flush=True)

    def close(self) -> None:
        self._line()
        self.stage = None
        print(f"fit {self.label}: finished in {time.perf_counter() - self.start:.1f} s", file=self.stream or sys.stderr,
              flush=True)
