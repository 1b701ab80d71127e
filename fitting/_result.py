"""What a fit returns: `FitResult` (parameters, family, ranking, intervals, report, pictures)."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

import numpy as np

import morphojax as mj


@dataclasses.dataclass
class FitResult:
    """Everything a fit found and how.

    params: fitted values by name; model: the fitted model or experiment; loss: final loss
    (in noise units); noise_floor: the loss expected if the target were a sample of the fitted
    parameters; history: list of {stage, start, evaluation, loss}, one row per design point and
    per step of the local search (its point's loss); timings: seconds per stage;
    stats: target and fit statistics; report: region statistics (spot counts, areas,
    eccentricity, Euler number); design: the global stage's points and losses; fields: the
    target field and one simulated field of the fit ("fit"), for previews; a full fit's
    also "samples", one field per seed of the noise floor.
    """

    params: dict
    model: Any
    loss: float
    noise_floor: float
    history: list
    timings: dict
    stats: dict
    report: dict
    design: list
    fields: dict
    config: dict
    target: dict
    family: str = ""
    score: float = float("nan")  # the loss with the config's fixed noise scales (same yardstick for every family)
    ranking: list = dataclasses.field(default_factory=list)
    intervals: dict = dataclasses.field(default_factory=dict)
    undetermined: list = dataclasses.field(default_factory=list)
    palette: list | None = None
    simulator: Any = dataclasses.field(default=None, repr=False)
    # the verdict (`fitting._verdict`): convincing on the held-out tile, in words, the numbers
    convincing: bool = False
    verdict: str = ""
    heldout: dict = dataclasses.field(default_factory=dict)
    rejected: str | None = None  # why the fitted coat is degenerate, or None
    correlated: list = dataclasses.field(default_factory=list)  # [[a, b], ...] moving together
    # what the fit's later stages share (`fitting._fit.FitState`), to go on from its best point
    resume: Any = dataclasses.field(default=None, repr=False, compare=False)

    @property
    def sample(self) -> np.ndarray:
        """One simulated field of the fit at lattice resolution, in [0, 1] with the pigment
        bright: the species compared with the target, so orientation and polarity are the
        target's after `invert`."""
        from ._palette import unit

        return unit(self.fields["fit"])

    def save_sample(self, path) -> Path:
        """Write `sample` as a grey PNG (one pixel per lattice cell)."""
        from PIL import Image

        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        Image.fromarray(np.round(255 * self.sample).astype(np.uint8), "L").save(path)
        return path

    def render(self, path=None, size=512, palette="photo", seed: int = 0):
        """The fitted coat as a large picture (PIL image; saved when `path` is given).

        size: pixels (an int for a square, or (width, height)); palette: "photo" (the
        target crop's colours, see `fitting.photo_palette`), "grey", or a list of
        (position, (r, g, b)) stops. Models are re-simulated on a larger wrapped lattice
        at the target's cells per pixel, so the picture wraps seamlessly; experiments tile
        their fitted field."""
        from ._palette import render_coat

        img = render_coat(self, size=size, palette=palette, seed=seed)
        if path is not None:
            Path(path).parent.mkdir(parents=True, exist_ok=True)
            img.save(path)
        return img

    def describe(self) -> str:
        """What the fit found, in words: the family, each parameter with its interval, which
        are not determined, and how far from the noise floor the fit is."""
        from ._report import describe

        return describe(self)

    def to_json(self) -> dict:
        """Everything in the result as a JSON-ready dict (top-level 'params')."""
        if isinstance(self.model, mj.AbstractModel):
            model = mj.model_to_dict(self.model)
        elif isinstance(self.model, mj.YoungCA):  # as models: {"type", "params"} (`YoungCA(**params)`)
            model = {"type": "YoungCA", "params": self.model.to_dict()}
        else:
            model = self.model.to_dict()
        return mj.to_jsonable({
            "params": self.params, "family": self.family, "loss": self.loss, "noise_floor": self.noise_floor,
            "loss_over_noise_floor": self.loss / self.noise_floor if self.noise_floor > 0 else None,
            "score": self.score if np.isfinite(self.score) else None,
            "convincing": bool(self.convincing), "verdict": self.verdict, "heldout": self.heldout,
            "rejected": self.rejected, "correlated": self.correlated,
            "ranking": self.ranking, "intervals": {k: list(v) for k, v in self.intervals.items()},
            "undetermined": list(self.undetermined), "summary": self.describe(), "palette": self.palette,
            "model": model, "target": self.target, "config": self.config, "timings": self.timings,
            "stats": self.stats, "report": self.report, "design": self.design, "history": self.history,
        })

    def save_json(self, path) -> Path:
        """Write `to_json()` to `path`; returns the path."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(self.to_json(), allow_nan=False, indent=1))
        return path

    def preview(self, path=None, scale: int | None = None):
        """Side-by-side picture target | fitted simulation | loss curve (PIL image); saved when `path` is given."""
        from ._report import preview

        img = preview(self, scale=scale)
        if path is not None:
            img.save(path)
        return img
