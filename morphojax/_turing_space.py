"""Turing spaces: where in a plane (or grid, or list) of parameters a model's homogeneous
state is Turing-unstable on a domain, and the wavelength the linear theory predicts there.

    space = mj.turing_space(mj.Turing(scale=3.0), mj.Lattice(), vary={"ratio": np.linspace(2, 40, 20),
                            "upper_a": [4.0, 6.2]}, shape=(50, 50))
    space.unstable        # (20, 2) bool
    space.wavelength      # (20, 2) cells, NaN where no mode grows
    space.at_limit        # (20, 2, species): the steady state sits on a saturation limit
    space.save("space.png")   # the map, labelled as a sweep's montage, + space.csv

`vary` is a sweep's (`mj.sweep`): a grid {name: values} in C order or a list of parameter
sets, parsed by the same code (`_sweep_members`); every member is `model.replace(**values)`,
built inside one vmapped program (`_stability.linear_stability`) from traced values, so a
plane of thousands of members is one compiled call per chunk. The domain's modes are
computed once.
"""

from __future__ import annotations

import csv
import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from PIL import Image, ImageDraw

from ._render import label_font, montage, png_path, to_image
from ._serialise import model_to_dict
from ._files import check_output_path
from ._stability import linear_stability, operator_modes
from .models._steady import solve, tolerance
from ._sweep_members import DT, GROWTH_RATE, grid_labels, label, member_model, sweep_members
from .domains import AbstractDomain, Lattice
from .models import AbstractModel

CHUNK = 1024  # members per compiled call (the last chunk is padded with its last member)
TILE = 36  # pixels per member on a labelled grid
LABELLED = 16  # the most rows or columns drawn as labelled tiles; larger planes are a heat map
STABLE, KINETIC, NO_STATE = (205, 205, 205), (90, 90, 90), (0, 0, 0)  # tiles without a wavelength
BEYOND = (150, 30, 30)  # no steady state within the limits: the reaction's own state lies beyond one
HATCH = (255, 0, 255)  # diagonal lines over a member whose steady state sits on a limit
HATCH_PERIOD = 4  # pixels between the hatching's lines (one pixel wide)


@dataclasses.dataclass
class TuringSpace:
    """The outcome of `turing_space`: one entry per member, shaped like the grid.

    Attributes:
        model: the base model; `names`: the varied parameters, in the order of `vary`;
        axes: each grid axis's values (None for an explicit list); values: per-member
        values {name: (n,) array}, members in C order of the grid;
        unstable: Turing-unstable (stable without diffusion, some mode grows with it);
        wavelength: the fastest-growing mode's wavelength (cells on lattices, the mesh's
        unit on meshes), NaN where no mode grows, inf where the uniform mode grows fastest;
        rate: the fastest growth rate; kinetic_rate: the rate without diffusion (> 0:
        unstable without diffusion, e.g. oscillating);
        converged: whether a homogeneous steady state was found (elsewhere everything is
        NaN and `unstable` False); steady_state: (*shape, species); at_limit: (*shape,
        species) whether it sits on a saturation limit (see `dispersion`: there the rates
        leave the clamp out and are an upper bound, and the run's wavelength may be far
        from `wavelength`; `table()`'s `at_limit` is True where any species does);
        beyond_limit: (*shape,) no steady state within the limits, but the reaction with
        the limits left out has one, outside them (e.g. Turing's (4, 4) with Ua = 3.5:
        the reaction pulls a back below its limit, so the clamp holds nothing still);
        domain: the domain's description; config: the base model and the run's settings.
    """

    model: AbstractModel
    names: tuple
    axes: tuple | None
    values: dict
    unstable: np.ndarray
    wavelength: np.ndarray
    rate: np.ndarray
    kinetic_rate: np.ndarray
    converged: np.ndarray
    steady_state: np.ndarray
    at_limit: np.ndarray
    beyond_limit: np.ndarray
    domain: str
    config: dict

    @property
    def shape(self) -> tuple:
        """(len(v1), len(v2), ...) for a grid, (n,) for an explicit list."""
        return self.unstable.shape

    def __len__(self):
        return int(self.unstable.size)

    def column(self, name) -> np.ndarray:
        """A varied parameter's values shaped like the grid."""
        if name not in self.values:
            raise ValueError(f"no varied parameter {name!r}; varied: {', '.join(self.names)}")
        return self.values[name].reshape(self.shape)

    def limited(self) -> np.ndarray:
        """Shaped like the grid: a steady state was found and some species sits on a
        saturation limit (the members the picture hatches)."""
        return self.converged & self.at_limit.reshape(self.shape + (-1,)).any(-1)

    def table(self) -> list[dict]:
        """One dict per member: its values, unstable, wavelength, rate, kinetic_rate,
        converged, at_limit (`limited()`: the state sits on a limit, so the linear theory
        leaves the clamp out) and beyond_limit (no state within the limits: the
        reaction's own lies beyond one)."""
        flat = {k: np.asarray(getattr(self, k)).reshape(-1) for k in
                ("unstable", "wavelength", "rate", "kinetic_rate", "converged")}
        flat |= {"at_limit": self.limited().reshape(-1), "beyond_limit": np.asarray(self.beyond_limit).reshape(-1)}
        rows = []
        for i in range(len(self)):
            row = {"member": i} | {n: float(self.values[n][i]) for n in self.names}
            row |= {k: (bool(v[i]) if v.dtype == bool else float(v[i])) for k, v in flat.items()}
            rows.append(row)
        return rows

    # ---- the picture ----
    def image(self, cmap="viridis") -> Image.Image:
        """The map as a picture: each member coloured by its predicted wavelength (one
        colour range for all), light grey where no mode grows, dark grey where the state is
        unstable without diffusion, black where no steady state was found, dark red where
        none was found within the limits because the reaction's own state lies beyond one
        (`beyond_limit`). Members whose steady state sits on a limit (`limited()`) are
        hatched with magenta diagonal lines over their colour: their prediction leaves the
        clamp out, so the run's wavelength may be far from the one drawn. Grids of at most
        `LABELLED` rows and columns are labelled tiles, with the sweep montage's labels
        (rows: the first names, columns: the last) and each tile's wavelength written on
        it; larger 2D grids are a heat map with the two ranges on its axes."""
        wl = np.where(self.unstable, self.wavelength, np.nan).reshape(-1)
        finite = wl[np.isfinite(wl)]
        lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0)
        title = self._title(lo, hi, finite.size > 0)
        colours = self._colours(wl, lo, hi, cmap)
        grid = self.axes is not None and len(self.axes) == 2
        if grid and max(self.shape) > LABELLED:
            scale = max(2, 320 // max(self.shape))  # about 320 pixels along the longer axis
            pixels = np.repeat(np.repeat(colours.reshape(self.shape + (3,)), scale, 0), scale, 1)
            marked = np.repeat(np.repeat(self.limited(), scale, 0), scale, 1)
            return _framed(Image.fromarray(_hatched(pixels, marked), "RGB"), self.names, self.axes, title)
        limited = self.limited().reshape(-1)
        tiles = [_tile(c, f"{w:.3g}" if np.isfinite(w) else "", mark) for c, w, mark in zip(colours, wl, limited)]
        if self.axes is None:
            captions = [label({n: self.values[n][i] for n in self.names}) for i in range(len(self))]
            return montage([_captioned(t, c) for t, c in zip(tiles, captions)], min(len(tiles), 6), title=title)
        rows, cols = grid_labels(self.names, self.axes)
        return montage(tiles, len(cols), row_labels=rows, col_labels=cols,
                       title=f"{title} | columns: {self.names[-1]}")

    def _colours(self, wl, lo, hi, cmap) -> np.ndarray:
        scale = to_image(np.where(np.isfinite(wl), wl, lo)[None, :], cmap=cmap, vmin=lo, vmax=max(hi, lo + 1e-12))
        colours = np.asarray(scale)[0].copy()
        converged = self.converged.reshape(-1)
        kinetic = self.kinetic_rate.reshape(-1) >= 0
        colours[~np.isfinite(wl)] = STABLE
        colours[converged & kinetic & ~np.isfinite(wl)] = KINETIC
        colours[~converged] = NO_STATE
        colours[~converged & self.beyond_limit.reshape(-1)] = BEYOND
        return colours.astype(np.uint8)

    def _title(self, lo, hi, any_unstable) -> str:
        fixed = {k: float(v) for k, v in self.model.parameters().items()
                 if k not in self.names and np.ndim(v) == 0 and np.isfinite(float(v))}
        parts = [type(self.model).__name__, label(fixed), self.domain]
        parts.append(f"colour: wavelength {lo:.3g}-{hi:.3g}" if any_unstable else "no member Turing-unstable")
        parts.append("grey: stable, dark: unstable without diffusion, black: no steady state, red: state beyond a "
                     "limit, magenta lines: state on a limit")
        return " | ".join(p for p in parts if p)

    def save(self, path, cmap="viridis") -> dict:
        """Write the picture (`path`, PNG) and the table (.csv next to it); return the paths."""
        path = png_path(path)
        check_output_path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        self.image(cmap=cmap).save(path, format="PNG")
        table = path.with_suffix(".csv")
        rows = self.table()
        with table.open("w", newline="") as f:
            writer = csv.writer(f)
            writer.writerow(list(rows[0]))
            for row in rows:
                writer.writerow([str(v).lower() if isinstance(v, bool) else v for v in row.values()])
        return {"png": path, "csv": table}


def _hatched(pixels, marked) -> np.ndarray:
    """`pixels` (rows, cols, 3) with the `HATCH` lines drawn where `marked` (rows, cols):
    every pixel whose row + column is a multiple of `HATCH_PERIOD`, so a member of two
    pixels or more on a side always shows one."""
    rows, cols = np.indices(marked.shape)
    out = np.array(pixels, np.uint8)
    out[marked & ((rows + cols) % HATCH_PERIOD == 0)] = HATCH
    return out


def _tile(colour, text, mark=False) -> Image.Image:
    img = Image.new("RGB", (TILE, TILE), tuple(int(c) for c in colour))
    if mark:
        img = Image.fromarray(_hatched(np.asarray(img), np.ones((TILE, TILE), bool)), "RGB")
    if text:
        draw = ImageDraw.Draw(img)
        box = draw.textbbox((0, 0), text, font=label_font())
        ink = "black" if sum(int(c) for c in colour) > 380 else "white"
        draw.text(((TILE - box[2]) // 2, (TILE - box[3]) // 2), text, fill=ink, font=label_font())
    return img


def _captioned(img, text) -> Image.Image:
    font = label_font()
    box = ImageDraw.Draw(img).textbbox((0, 0), text, font=font)
    canvas = Image.new("RGB", (max(img.width, box[2] + 4), img.height + box[3] + 6), "white")
    ImageDraw.Draw(canvas).text((2, 1), text, fill="black", font=font)
    canvas.paste(img, (0, canvas.height - img.height))
    return canvas


def _framed(picture, names, axes, title) -> Image.Image:
    """A heat map of a large 2D grid (rows: the first name, top to bottom; columns: the
    second, left to right) with each axis's name and end values beside it, as a parameter
    map's picture (`map_image`) has them."""
    font = label_font()
    probe = ImageDraw.Draw(Image.new("RGB", (1, 1)))

    def size(t):
        b = probe.textbbox((0, 0), t, font=font)
        return b[2] - b[0], b[3] - b[1]

    y_first, y_last = f"{axes[0][0]:.3g}", f"{axes[0][-1]:.3g}"
    x_first, x_last = f"{axes[1][0]:.3g}", f"{axes[1][-1]:.3g}"
    line = size("Ag")[1] + 6
    left = max(size(y_first)[0], size(y_last)[0], size(names[0])[0]) + 8
    top = line if title else 0
    width = max(left + picture.width + 4, size(title)[0] + 8 if title else 0)
    canvas = Image.new("RGB", (width, top + picture.height + 2 * line), "white")
    canvas.paste(picture, (left, top))
    d = ImageDraw.Draw(canvas)
    if title:
        d.text((4, 2), title, fill="black", font=font)
    d.text((2, top), y_first, fill="black", font=font)
    d.text((2, top + picture.height - size(y_last)[1] - 2), y_last, fill="black", font=font)
    d.text((2, top + picture.height // 2 - line // 2), f"{names[0]} v", fill="black", font=font)
    below = top + picture.height + 2
    d.text((left, below), x_first, fill="black", font=font)
    d.text((left + picture.width - size(x_last)[0], below), x_last, fill="black", font=font)
    d.text((left + (picture.width - size(f"{names[1]} ->")[0]) // 2, below + line), f"{names[1]} ->", fill="black",
           font=font)
    return canvas


def turing_space(model: AbstractModel, domain: AbstractDomain | None = None, vary=None, shape=None, *,
                 modes: int | None = None, guess=None) -> TuringSpace:
    """Map where `model`'s homogeneous state is Turing-unstable on `domain` over the
    parameter sets of `vary`, and the wavelength of the fastest-growing mode there.

    Args:
        model: the base model; every member is `model.replace(**its values)`.
        domain, shape, modes, guess: as in `dispersion` (a lattice's shape is needed: its
            modes are that lattice's own).
        vary: as in `sweep`: a grid {"ratio": [...], "upper_a": [...]} (C order, the last
            name fastest) or a list of parameter sets; names are the model's
            `parameters()` (a run's `dt` and `growth_rate` do not enter the linear theory).

    Returns a `TuringSpace`: NumPy arrays shaped like the grid, `.save(path)` for its
    picture and table. Members are vmapped, `CHUNK` at a time in one compiled program.
    """
    if not isinstance(model, AbstractModel):
        raise ValueError(f"turing_space: model must be a morphojax model such as mj.Turing(...) (got {model!r})")
    domain = Lattice() if domain is None else domain
    if vary is None:
        raise ValueError(f"turing_space: vary is required; name at least one of {', '.join(model.parameters())}")
    try:
        names, axes, values, grid = sweep_members(model, vary, None, 0.0)
    except ValueError as err:
        text = str(err)
        raise ValueError("turing_space:" + text[len("sweep:"):] if text.startswith("sweep:") else text) from None
    for name in names:
        if name in (DT, GROWTH_RATE):
            raise ValueError(f"turing_space: {name!r} is a run's setting, not the model's; the linear theory "
                             f"varies the model's parameters: {', '.join(model.parameters())}")
    for i in range(len(values[names[0]])):  # every member concretely, naming the first bad one
        vals = {k: float(values[k][i]) for k in names}
        try:
            member_model(model, None, 0.0, vals)
        except ValueError as err:
            raise ValueError(f"turing_space member {i} ({label(vals)}): {err}") from None
    eig, wavelengths = operator_modes(domain, shape, modes)

    def one(vals):
        member = member_model(model, None, 0.0, vals)[0]
        d = linear_stability(member, eig, wavelengths, guess)
        return (d.turing_unstable, d.fastest_wavelength, d.fastest_rate, d.kinetic_rate, d.converged,
                d.steady_state, d.at_limit, ~d.converged & _beyond_limit(member, guess))

    run = jax.jit(jax.vmap(one))
    n = len(values[names[0]])
    size = min(n, CHUNK)
    pieces = []
    for start in range(0, n, size):
        idx = np.minimum(np.arange(start, start + size), n - 1)
        out = run({k: jnp.asarray(values[k][idx]) for k in names})
        pieces.append([np.asarray(o)[: min(size, n - start)] for o in out])
    unstable, wl, rate, kinetic, ok, steady, at_limit, beyond = (np.concatenate(p) for p in zip(*pieces))
    config = {"model": model_to_dict(model), "domain": domain.description, "shape": None if shape is None else
              [int(v) for v in np.atleast_1d(shape)], "modes": int(np.size(eig))}
    return TuringSpace(model=model, names=names, axes=axes, values=values, unstable=unstable.reshape(grid),
                       wavelength=wl.reshape(grid), rate=rate.reshape(grid), kinetic_rate=kinetic.reshape(grid),
                       converged=ok.reshape(grid), steady_state=steady.reshape(grid + steady.shape[1:]),
                       at_limit=at_limit.reshape(grid + at_limit.shape[1:]), beyond_limit=beyond.reshape(grid),
                       domain=domain.description,
                       config=config)


class _Unlimited(eqx.Module):
    """`model` with its saturation limits left out, as `solve` reads a model (its
    reaction, species, closed-form state and limits): the reaction's own steady state."""

    model: AbstractModel

    @property
    def n_species(self):
        return self.model.n_species

    @property
    def species(self):
        return self.model.species

    @property
    def lower(self):
        return jnp.full((self.model.n_species,), -jnp.inf)

    @property
    def upper(self):
        return jnp.full((self.model.n_species,), jnp.inf)

    def reaction(self, x):
        return self.model.reaction(x)

    def unclamped_state(self):
        return self.model.unclamped_state()


def _beyond_limit(model, guess) -> jax.Array:
    """() whether the reaction, its limits left out, has a steady state (Newton's method
    from the same start) that lies outside the limits: then no state within them may exist
    because the reaction pushes back from the limit (a state held by the clamp needs a
    reaction pushing past it)."""
    x, ok, _ = solve(_Unlimited(model), guess)
    x = x.reshape(model.n_species)
    lo, hi = (jnp.broadcast_to(jnp.asarray(v, x.dtype).reshape(-1), x.shape) for v in (model.lower, model.upper))
    near = tolerance(x.dtype) * (1.0 + jnp.abs(x))
    return ok.reshape(()) & jnp.any((x < lo - near) | (x > hi + near))
