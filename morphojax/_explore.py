"""Live exploration in Jupyter: sliders for a model's parameters and a picture that re-runs,
and a clickable parameter map of a sweep.

`mj.explore(model, state, steps, dt)` shows one slider per scalar parameter and the run's
final pattern (Ready-style). The run is one compiled program whose parameters are traced
arrays, so moving a slider re-runs it without compiling again; a dt beyond the stability
limit of the new values is reported instead of run.

`mj.explore_sweep(result)` draws a sweep as a map of buttons, one per member laid out as
the montage (rows: the first parameter, columns: the last), coloured by a column of its
table (the dominant wavelength by default, or the pattern class); clicking one opens that
member: its final pattern, its parameters and descriptors. Needs ipywidgets (`pip install
-e ".[notebook]"`).
"""

from __future__ import annotations

import io
import math
import time

import jax
import numpy as np

from ._render import colormap_table, normalise, to_image
from ._simulate import simulate
from .domains import as_domain


class Explorer:
    """Sliders, a picture and a status line; `widget` is what Jupyter shows.

    Attributes:
        values: the current parameter values by name.
        widget: the ipywidgets box (displayed when the Explorer is the cell's result).
        sliders: name -> slider; `image`: the picture; `status`: the status line.
    """

    def __init__(self, model, state, steps: int, dt, *, names=None, ranges=None, species=-1, cmap="inferno",
                 scale: int = 2, **simulate_kwargs):
        import ipywidgets as widgets

        scalar = {n: float(v) for n, v in model.parameters().items() if np.ndim(v) == 0 and math.isfinite(float(v))}
        names = list(scalar) if names is None else list(names)
        unknown = [n for n in names if n not in scalar]
        if unknown:
            raise ValueError(f"explore.names: {unknown} are not finite scalar parameters of {type(model).__name__}; "
                             f"choose from {', '.join(scalar)}")
        ranges = dict(ranges or {})
        self.model, self.state, self.steps, self.dt = model, state, steps, float(dt)
        self.domain = as_domain(simulate_kwargs.pop("domain", None), stencil=simulate_kwargs.pop("stencil", None),
                                boundary=simulate_kwargs.pop("boundary", None))
        self.species, self.cmap, self.scale = species, cmap, scale
        self.values = {n: scalar[n] for n in names}
        kwargs = dict(domain=self.domain, check_dt=False, **simulate_kwargs)
        self._run = jax.jit(lambda values: simulate(model.replace(**values), state, steps, dt, **kwargs).fields)
        self.sliders = {}
        for n in names:
            lo, hi = ranges.get(n, _default_range(scalar[n]))
            self.sliders[n] = widgets.FloatSlider(value=scalar[n], min=lo, max=hi, step=(hi - lo) / 100,
                                                  description=n, continuous_update=False,
                                                  style={"description_width": "initial"})
            self.sliders[n].observe(self._moved, names="value")
        self.image = widgets.Image(format="png")
        self.status = widgets.HTML()
        self.widget = widgets.HBox([widgets.VBox(list(self.sliders.values()) + [self.status]), self.image])
        self.update()

    def _moved(self, change):
        self.values[change["owner"].description] = float(change["new"])
        self.update()

    def update(self) -> None:
        """Re-run with the current values and show the result (or why it was not run)."""
        model = self.model.replace(**self.values)
        limit = self.domain.max_stable_dt(model.max_diffusion())
        if self.dt > limit:
            self.status.value = (f"<b>not run</b>: dt = {self.dt:g} is beyond the explicit-Euler limit for these "
                                 f"values; the largest stable dt is {limit:.4g}")
            return
        t0 = time.perf_counter()
        fields = np.asarray(self._run({n: np.float32(v) for n, v in self.values.items()}))
        index = self.state.index(self.species) if self.species != -1 else fields.shape[0] - 1
        shown = fields[index][tuple(slice(0, n) for n in self.state.shape)]
        if not np.isfinite(shown).all():
            self.status.value = "<b>blew up</b>: the run became non-finite; lower dt or change the values"
            return
        buffer = io.BytesIO()
        to_image(shown, cmap=self.cmap, scale=self.scale).save(buffer, format="PNG")
        self.image.value = buffer.getvalue()
        self.status.value = f"{self.steps} steps in {time.perf_counter() - t0:.2f} s"

    def _repr_mimebundle_(self, **kwargs):
        return self.widget._repr_mimebundle_(**kwargs)


def _default_range(value: float) -> tuple[float, float]:
    """A quarter to four times a positive value; value +- 1 (at least +- |value|) otherwise."""
    if value > 0:
        return value / 4, value * 4
    half = max(1.0, abs(value))
    return value - half, value + half


def explore(model, state, steps: int, dt, **kwargs) -> Explorer:
    """Sliders for `model`'s scalar parameters and the final pattern of `simulate(model,
    state, steps, dt)`, re-run as they move (in Jupyter).

    Keyword arguments: `names` (the parameters to slide; default all finite scalars),
    `ranges` (name -> (low, high); default a quarter to four times the value), `species`,
    `cmap`, `scale` for the picture, and any `simulate` option (domain, bounds, ...).
    """
    return Explorer(model, state, steps, dt, **kwargs)


class SweepExplorer:
    """A sweep's parameter map as buttons and the member under the last click.

    Attributes:
        result: the `SweepResult`; buttons: one per member (flat order); image: the opened
        member's final pattern; details: its parameters and descriptors; selected: its
        flat index (None before a click); widget: what Jupyter shows.
    """

    def __init__(self, result, colour_by: str = "wavelength", species=-1, cmap="inferno", scale: int = 3):
        import ipywidgets as widgets

        self.result, self.species, self.cmap, self.scale = result, species, cmap, scale
        self.selected = None
        colours = _map_colours(result, colour_by)
        rows, cols = _grid(result.shape)
        self.buttons = []
        for i in range(len(result)):
            values = {n: float(result.values[n][i]) for n in result.names}
            unstable = result.blowup_step[i] >= 0
            button = widgets.Button(description="NaN" if unstable else "", tooltip=_label(values),
                                    layout=widgets.Layout(width="28px", height="28px", padding="0"))
            button.style.button_color = "#888888" if unstable else colours[i]
            button.on_click(lambda _, i=i: self.open(i))
            self.buttons.append(button)
        grid = widgets.GridBox(self.buttons, layout=widgets.Layout(
            grid_template_columns=f"repeat({cols}, 30px)", grid_gap="2px"))
        axes = f"rows: {', '.join(result.names[:-1]) or '-'}; columns: {result.names[-1]}" if rows > 1 else \
            f"columns: {', '.join(result.names)}"
        caption = widgets.HTML(f"colour: {colour_by}; {axes}; click a member to open it")
        self.image = widgets.Image(format="png")
        self.details = widgets.HTML()
        self.widget = widgets.HBox([widgets.VBox([caption, grid]), widgets.VBox([self.image, self.details])])

    def open(self, i) -> None:
        """Show member `i` (flat index or grid tuple): its final pattern, parameters and table row."""
        from ._sweep_result import species_index

        i = self.result.index(i)
        self.selected = i
        k = species_index(self.result.species, self.species)
        arrays = self.result.arrays()
        field = arrays.reshape((len(self.result),) + arrays.shape[-3:])[i, k]
        buffer = io.BytesIO()
        to_image(np.where(np.isfinite(field), field, 0.0), cmap=self.cmap, scale=self.scale).save(buffer, format="PNG")
        self.image.value = buffer.getvalue()
        row = self.result.table[i] if self.result.table else {}
        shown = {k: v for k, v in row.items() if k != "index"}
        self.details.value = f"<b>member {i}</b><br>" + "<br>".join(
            f"{k} = {v:.4g}" if isinstance(v, float) else f"{k} = {v}" for k, v in shown.items())

    def _repr_mimebundle_(self, **kwargs):
        return self.widget._repr_mimebundle_(**kwargs)


def _grid(shape) -> tuple[int, int]:
    """(rows, cols) of the map: the last axis is the columns, the others combine into rows."""
    cols = int(shape[-1])
    return int(np.prod(shape[:-1])) if len(shape) > 1 else 1, cols


def _label(values: dict) -> str:
    return ", ".join(f"{n}={v:.3g}" for n, v in values.items())


def _map_colours(result, column: str) -> list:
    """A hex colour per member: numeric columns through the colour map over their finite
    range, categories (e.g. "pattern") each their own colour."""
    data = np.asarray(result.column(column)).ravel()
    table = colormap_table("viridis")
    if data.dtype.kind in "fiu":
        picks = [table[int(round(v * 255))] for v in normalise(data.astype(float))]
    else:
        names = sorted(set(data.tolist()))
        picks = [table[int(round(255 * names.index(v) / max(len(names) - 1, 1)))] for v in data.tolist()]
    return ["#%02x%02x%02x" % tuple(int(c) for c in rgb) for rgb in picks]


def explore_sweep(result, colour_by: str = "wavelength", **kwargs) -> SweepExplorer:
    """A clickable parameter map of a `sweep` result (in Jupyter): one button per member,
    coloured by the table column `colour_by` ("wavelength", "pattern", "spots", ... or a
    varied parameter); a click shows that member's final pattern, parameters and
    descriptors. Keyword arguments: `species`, `cmap`, `scale` of the picture."""
    return SweepExplorer(result, colour_by, **kwargs)
