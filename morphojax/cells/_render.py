"""Pictures of off-lattice cells: discs, Voronoi tiles, interpolated textures and SVG
(thesis sections 4.6-4.7).

The thesis's interface draws every cell as a filled circle coloured by one reagent through
a colour map, with a short line segment showing the orientation of polarised cells (4.7);
it also exports the cell positions and colours as SVG and interpolates the cells' values
onto a high-resolution texture with natural-neighbour coordinates (CGAL 4.9, section 4.6).

Geometry shared by every picture: lengths are cell radii and every cell has radius 1
(thesis 4.4); +y is up, so row 0 of an image holds the largest y. The pictures of the
cells (`render_cells`, `write_cells_svg`) frame the live cells' bounding box grown by the
cell radius and a `margin`, keeping the aspect ratio; the textures (`cells_field`,
`cells_texture`) cover the box grown by the cell radius alone (the tissue's extent), whose
aspect ratio a `size` of (width, height) may stretch, as a texture mapped onto a model is.

Colours come from `morphojax._render` (`to_image`: the same normalisation and colour map
as every lattice picture); the range [vmin, vmax] defaults to the live cells' values.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw
from scipy.spatial import Delaunay, QhullError, cKDTree

from .._checks import check_choice, check_range
from .._render import _rgb, to_image
from .._files import write_atomically
from ._state import Cells

STYLES = ("discs", "voronoi")
METHODS = ("linear", "nearest", "natural")
CELL_RADIUS = 1.0  # every cell is a unit disc (thesis 4.4)
VORONOI_REACH = 1.5  # "voronoi" pixels farther than this from every cell stay background
MAX_SIDE = 16384  # pixels: the largest image side accepted
POLARITY_LENGTH = 1.0  # cell radii: a polarity segment runs from the centre to the rim
POLARITY_STROKE = 0.15  # cell radii: the width of a polarity segment in SVG
SVG_SCALE = 10.0  # the SVG's width and height attributes: pixels per cell radius
CHUNK = 1 << 16  # natural-neighbour queries handled at once (bounds the memory used)


# ---- the cells and their values ---------------------------------------------------------------
def _live(cells: Cells, reagent, who: str) -> tuple[dict, np.ndarray]:
    """The live cells' buffers (float64 positions) and the chosen reagent's values."""
    if not isinstance(cells, Cells):
        raise ValueError(f"{who} needs a Cells state (got {type(cells).__name__})")
    live = cells.live()
    if live["position"].shape[0] == 0:
        raise ValueError(f"{who} needs at least one live cell (the cells' count is 0)")
    live["position"] = live["position"].astype(np.float64)
    return live, live["concentration"][_reagent_row(cells, reagent)].astype(np.float64)


def _reagent_row(cells: Cells, reagent) -> int:
    """The row of `reagent` (a name or an index; None: the first declared reagent, which
    the thesis's interface shows first)."""
    if reagent is None:
        return 0
    if isinstance(reagent, str):
        return cells.index(reagent)  # names the reagents when it is unknown
    if isinstance(reagent, (int, np.integer)) and not isinstance(reagent, bool) and 0 <= reagent < cells.n_species:
        return int(reagent)
    raise ValueError(f"reagent must be one of {', '.join(cells.species)} or an index in "
                     f"[0, {cells.n_species - 1}] (got {reagent!r})")


def _colours(values, cmap, vmin, vmax) -> np.ndarray:
    """(n, 3) uint8 colours of `values`: the colour map of `to_image`, the range defaulting
    to the values' own."""
    return np.asarray(to_image(np.asarray(values, float)[None, :], cmap, vmin, vmax))[0]


def _value_range(values, vmin, vmax) -> tuple[float, float]:
    """[vmin, vmax] with the live cells' own minimum and maximum as defaults."""
    finite = values[np.isfinite(values)]
    lo = (float(finite.min()) if finite.size else 0.0) if vmin is None else float(vmin)
    hi = (float(finite.max()) if finite.size else 1.0) if vmax is None else float(vmax)
    return lo, hi


# ---- framing --------------------------------------------------------------------------------
def _image_size(size, box_width: float, box_height: float) -> tuple[int, int]:
    """(width, height) in pixels: an integer `size` is the longer side, the other follows the
    box's aspect ratio; a pair is taken as it is."""
    if isinstance(size, (int, np.integer)) and not isinstance(size, bool) and 1 <= size <= MAX_SIDE:
        if box_width >= box_height:
            return int(size), max(1, round(size * box_height / box_width))
        return max(1, round(size * box_width / box_height)), int(size)
    if (isinstance(size, (tuple, list)) and len(size) == 2
            and all(isinstance(s, (int, np.integer)) and not isinstance(s, bool) and 1 <= s <= MAX_SIDE for s in size)):
        return int(size[0]), int(size[1])
    raise ValueError(f"size must be an integer number of pixels or a (width, height) pair of integers, "
                     f"each in [1, {MAX_SIDE}] (got {size!r})")


def _box(position: np.ndarray, grow: float) -> tuple[np.ndarray, np.ndarray]:
    """The bounding box of the cell centres grown by `grow` on every side: (low, high)."""
    return position.min(axis=0) - grow, position.max(axis=0) + grow


class _Fit:
    """The box (low, high) fitted into a width x height image keeping its aspect ratio, centred:
    `scale` pixels per cell radius; x grows to the right and y upwards."""

    def __init__(self, low, high, width: int, height: int):
        self.width, self.height = width, height
        self.centre = (np.asarray(low) + np.asarray(high)) / 2
        extent = np.asarray(high) - np.asarray(low)
        self.scale = min(width / extent[0], height / extent[1])

    def pixel_centres(self) -> np.ndarray:
        """(height, width, 2) world coordinates of the pixel centres."""
        x = self.centre[0] + (np.arange(self.width) + 0.5 - self.width / 2) / self.scale
        y = self.centre[1] - (np.arange(self.height) + 0.5 - self.height / 2) / self.scale
        return np.stack(np.meshgrid(x, y), axis=-1)

    def to_pixels(self, xy) -> np.ndarray:
        """World points to Pillow's drawing coordinates (pixel (row, col) centred on (col, row))."""
        xy = np.asarray(xy, float)
        col = (xy[..., 0] - self.centre[0]) * self.scale + self.width / 2 - 0.5
        row = self.height / 2 - (xy[..., 1] - self.centre[1]) * self.scale - 0.5
        return np.stack([col, row], axis=-1)


def texture_pixel_centres(cells, size=512) -> np.ndarray:
    """(height, width, 2) world coordinates of the pixel centres of a texture of the live
    cells (`Cells`, or their (n, 2) centres): the box of the cell centres grown by the cell
    radius, stretched onto the whole image, row 0 at the top."""
    if isinstance(cells, Cells):
        position = _live(cells, None, "texture_pixel_centres")[0]["position"]
    else:
        position = np.asarray(cells, float)
        if position.ndim != 2 or position.shape[1:] != (2,) or not len(position):
            raise ValueError(f"texture_pixel_centres needs Cells or (n >= 1, 2) centres (got shape {position.shape})")
    low, high = _box(position, CELL_RADIUS)
    width, height = _image_size(size, *(high - low))
    x = low[0] + (np.arange(width) + 0.5) * (high[0] - low[0]) / width
    y = high[1] - (np.arange(height) + 0.5) * (high[1] - low[1]) / height
    return np.stack(np.meshgrid(x, y), axis=-1)


# ---- cells as discs or Voronoi tiles ---------------------------------------------------------
def render_cells(cells: Cells, reagent=None, *, size=512, style: str = "discs", cmap="inferno", vmin=None,
                vmax=None, background="black", polarity: bool = False, polarity_colour="white",
                margin: float = 1.0) -> Image.Image:
    """The live cells as a picture, coloured by one reagent (thesis 4.7, Fig. 4.3).

    Args:
        cells: concrete `Cells`; only the live ones (the leading `count`) are drawn.
        reagent: a reagent name or index (default: the first declared reagent).
        size: the longer side in pixels (the other follows the aspect ratio), or
            (width, height), into which the cells' box is fitted keeping its aspect ratio.
        style: "discs" paints every cell as a disc of radius 1 (the thesis's filled
            circles); "voronoi" gives every pixel within 1.5 cell radii of a cell the colour
            of its nearest cell (a gap-free tiling, background beyond).
        cmap, vmin, vmax: the colour map (name, `Gradient` or table) and its range
            (default: the live cells' minimum and maximum).
        background: colour of the pixels no cell covers.
        polarity: draw a segment from each polarised cell's centre to its rim along its
            polarity angle (thesis 4.7), in `polarity_colour`.
        margin: room around the cells' discs, in cell radii.

    A pixel belongs to the cell nearest to its centre when that cell is within reach (1 or
    1.5 cell radii), so overlapping discs (just after a division) split their overlap
    evenly instead of in drawing order; a disc narrower than a pixel still colours the pixel
    holding its centre.
    """
    check_choice(style, "style", STYLES)
    check_range(margin, "margin", low=0.0)
    live, values = _live(cells, reagent, "render_cells")
    position = live["position"]
    low, high = _box(position, CELL_RADIUS + float(margin))
    fit = _Fit(low, high, *_image_size(size, *(high - low)))
    colours = _colours(values, cmap, *_value_range(values, vmin, vmax))
    reach = CELL_RADIUS if style == "discs" else VORONOI_REACH
    reach = max(reach, np.sqrt(0.5) / fit.scale * 1.0001)  # at least half a pixel's diagonal
    rgb = _nearest_cell_pixels(position, colours, fit.pixel_centres(), reach, _rgb(background))
    image = Image.fromarray(rgb, "RGB")
    if polarity:
        _draw_polarity(image, fit, position, live["polarity"], live["polarised"], _rgb(polarity_colour))
    return image


def _nearest_cell_pixels(position, colours, pixels, reach: float, background) -> np.ndarray:
    """(height, width, 3): each pixel the colour of the cell nearest its centre when that
    cell lies within `reach`, `background` elsewhere."""
    distance, nearest = cKDTree(position).query(pixels.reshape(-1, 2), distance_upper_bound=reach)
    covered = np.isfinite(distance)  # a miss has distance inf and index n
    rgb = np.empty((distance.size, 3), np.uint8)
    rgb[:] = background
    rgb[covered] = colours[nearest[covered]]
    return rgb.reshape(*pixels.shape[:2], 3)


def _draw_polarity(image, fit: _Fit, position, angle, polarised, colour) -> None:
    """One segment per polarised cell, centre to rim along its angle (in place)."""
    tips = position + POLARITY_LENGTH * np.stack([np.cos(angle), np.sin(angle)], axis=-1)
    start, end = fit.to_pixels(position[polarised]), fit.to_pixels(tips[polarised])
    width = max(1, round(fit.scale / 6))
    draw = ImageDraw.Draw(image)
    for (x0, y0), (x1, y1) in zip(start.tolist(), end.tolist()):
        draw.line((x0, y0, x1, y1), fill=colour, width=width)


# ---- interpolated textures -----------------------------------------------------------------
def cells_field(cells: Cells, reagent=None, *, size=512, method: str = "linear") -> np.ndarray:
    """One reagent interpolated from the live cells onto a regular grid (thesis 4.6's
    high-quality texture): a (height, width) float64 array, row 0 the largest y.

    The grid covers the box of the cell centres grown by the cell radius, stretched onto
    `size` (an integer: the longer side, the aspect ratio kept; or (width, height));
    pixel (i, j) samples the point (x0 + (j + 1/2) w / width, y1 - (i + 1/2) h / height)
    of the box [x0, x0 + w] x [y1 - h, y1] (see `texture_pixel_centres`).

    `method`: "linear" interpolates linearly on the Delaunay triangulation of the cells;
    "natural" uses Sibson's natural-neighbour coordinates (the thesis's CGAL method: the
    weight of a cell is the area the query point's Voronoi cell takes from that cell's);
    "nearest" takes the nearest cell's value. Outside the cells' convex hull (and
    everywhere when the cells are fewer than three or collinear) every method takes the
    nearest cell's value. Linear and natural interpolation both reproduce the cell values
    at the cells and any linear function of position exactly inside the hull.
    """
    live, values = _live(cells, reagent, "cells_field")
    return _field(live["position"], values, size, method)


def cells_texture(cells: Cells, reagent=None, *, size=512, cmap="inferno", vmin=None, vmax=None,
                  method: str = "linear") -> Image.Image:
    """`cells_field` through a colour map: the thesis's interpolated texture (4.6, `texture
    size`; Figs. 7.16-7.19). The range [vmin, vmax] defaults to the live cells' values, so
    the texture's colours match `render_cells`'s."""
    live, values = _live(cells, reagent, "cells_texture")
    return to_image(_field(live["position"], values, size, method), cmap, *_value_range(values, vmin, vmax))


def _field(position, values, size, method: str) -> np.ndarray:
    """`values` at the cells interpolated onto the texture's pixel centres (see `cells_field`)."""
    check_choice(method, "method", METHODS)
    pixels = texture_pixel_centres(position, size)
    return _interpolate(position, values, pixels.reshape(-1, 2), method).reshape(pixels.shape[:2])


def _interpolate(points, values, xy, method: str) -> np.ndarray:
    """`values` at `points` interpolated to the query points `xy` ((q, 2)) by `method`."""
    nearest = cKDTree(points).query(xy)[1]
    field = values[nearest]
    if method == "nearest":
        return field
    triangulation = _delaunay(points)
    if triangulation is None:  # no area to interpolate over: every query lies outside the hull
        return field
    corners, across = _counter_clockwise(triangulation)
    start = triangulation.vertex_to_simplex[nearest]  # -1 for a cell Qhull dropped as a duplicate
    simplex, weights = _locate(points, corners, across, xy, np.where(start >= 0, start, 0))
    inside = simplex >= 0
    field[inside] = (weights[inside] * values[corners[simplex[inside]]]).sum(-1)
    if method == "natural":
        field[inside] = _natural_neighbour(points, corners, across, values, xy[inside], simplex[inside], field[inside])
    return field


def _delaunay(points) -> Delaunay | None:
    """The Delaunay triangulation of the cells, or None when they span no area (fewer than
    three, or collinear)."""
    try:
        return Delaunay(points)
    except (QhullError, ValueError):
        return None


def _cross(u, v):
    """The z component of the cross product of 2D vectors (twice a signed triangle area)."""
    return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]


def _counter_clockwise(triangulation: Delaunay) -> tuple[np.ndarray, np.ndarray]:
    """The triangles' corners ordered counter-clockwise, and the neighbour across the edge
    opposite each corner (-1 on the hull), reordered alike."""
    corners = triangulation.simplices.copy()
    across = triangulation.neighbors.copy()
    p = triangulation.points[corners]
    clockwise = _cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]) < 0
    corners[clockwise] = corners[clockwise][:, [0, 2, 1]]
    across[clockwise] = across[clockwise][:, [0, 2, 1]]
    return corners, across


def _barycentric(points, corners, triangle, xy) -> np.ndarray:
    """(q, 3) barycentric coordinates of the points `xy` in their counter-clockwise triangles."""
    p0, p1, p2 = (points[corners[triangle, k]] for k in range(3))
    twice_area = _cross(p1 - p0, p2 - p0)[:, None]
    return np.stack([_cross(p1 - xy, p2 - xy), _cross(p2 - xy, p0 - xy), _cross(p0 - xy, p1 - xy)], -1) / twice_area


def _locate(points, corners, across, xy, start) -> tuple[np.ndarray, np.ndarray]:
    """The triangle holding each query point (-1 outside the hull) and its barycentric
    coordinates, by a visibility walk from `start` (a triangle at the nearest cell, a step or
    two away): step across the edge the point lies farthest beyond, until no edge has it
    beyond; stepping out across a hull edge puts the point outside the convex hull. The walk
    never cycles on a Delaunay triangulation (Edelsbrunner's acyclicity theorem, 1990). Plain NumPy: scipy's
    `find_simplex` first builds its transforms with threaded LAPACK calls, slow on a busy
    machine."""
    tolerance = 1e-12
    simplex = start.copy()
    weights = np.zeros((len(xy), 3))
    active = np.arange(len(xy))
    for _ in range(len(corners) + 1):
        if not active.size:
            break
        w = _barycentric(points, corners, simplex[active], xy[active])
        weights[active] = w
        worst = w.argmin(axis=1)
        outside = w[np.arange(len(active)), worst] < -tolerance
        step = across[simplex[active[outside]], worst[outside]]
        simplex[active[outside]] = step  # -1: out across the hull, and the walk ends there
        active = active[outside][step >= 0]
    return simplex, weights


# ---- Sibson's natural-neighbour interpolation -----------------------------------------------
def _circumcentre(a, b, c) -> np.ndarray:
    """Circumcentres of the triangles (a, b, c) (arrays (..., 2)); infinite when collinear."""
    b, c, origin = b - a, c - a, a
    bb, cc = (b * b).sum(-1), (c * c).sum(-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        d = 2.0 * _cross(b, c)
        return origin + np.stack([(c[..., 1] * bb - b[..., 1] * cc) / d, (b[..., 0] * cc - c[..., 0] * bb) / d], -1)


def _natural_neighbour(points, corners, across, values, xy, simplex, fallback) -> np.ndarray:
    """Sibson's natural-neighbour interpolant (see `_sibson`), `CHUNK` queries at a time."""
    centre = _circumcentre(*(points[corners[:, k]] for k in range(3)))
    radius2 = ((points[corners[:, 0]] - centre) ** 2).sum(-1)
    triangles = (points, corners, across, centre, radius2)
    return np.concatenate([_sibson(triangles, values, xy[i:i + CHUNK], simplex[i:i + CHUNK], fallback[i:i + CHUNK])
                           for i in range(0, len(xy), CHUNK)] or [fallback])


def _sibson(triangles, values, xy, simplex, fallback) -> np.ndarray:
    """Sibson's natural-neighbour interpolant at the query points `xy` inside the hull
    (`simplex`: the triangle holding each), computed exactly from the Delaunay triangulation.

    Inserting a query point x removes the triangles whose circumcircle holds x (the
    Bowyer-Watson cavity); x's new Voronoi cell is what it takes from its natural neighbours
    (the cavity's vertices), and the area it takes from neighbour a is a polygon along a's
    old Voronoi edges, through the circumcentres C_T of the cavity triangles T around a,
    closed by a piece of the bisector of x and a. The shoelace formula taken about the
    midpoint of x and a, which lies on that bisector, drops the closing piece, so the area
    is a sum over the cavity triangles at a of cross products of consecutive chain points:
    C of the triangle across the edge before T (or, where that edge bounds the cavity, the
    circumcentre of x and the edge), then C_T, then, where the edge after T bounds the
    cavity, the circumcentre of x and that edge. Each (query, cavity triangle) pair thus
    adds its share independently, fully vectorised. Queries on a hull edge (where the
    Sibson interpolant is the linear one) or on a cell keep `fallback`.
    """
    points, corners, across, centre, radius2 = triangles
    query, cavity, keys = _cavities(xy, simplex, across, centre, radius2)

    def in_cavity(neighbour):
        return (neighbour >= 0) & _members(query * len(corners) + neighbour, keys)

    x = xy[query]
    numerator = np.zeros(len(xy))
    area = np.zeros(len(xy))
    c_t = centre[cavity]
    for k in range(3):  # the cavity triangle (a, b, c) as seen from each of its corners a
        a, b, c = (corners[cavity, (k + j) % 3] for j in range(3))
        before, after = across[cavity, (k + 2) % 3], across[cavity, (k + 1) % 3]  # edges ab, ca
        origin = (x + points[a]) / 2
        # the chain enters T from the triangle across ab, or where ab bounds the cavity
        # from x's new Voronoi vertex on it: the circumcentre of (x, a, b)
        entry = centre[before]
        opening = ~in_cavity(before)
        entry[opening] = _circumcentre(x[opening], points[a[opening]], points[b[opening]])
        term = _cross(entry - origin, c_t - origin)
        # where ca bounds the cavity the chain leaves T for x's new vertex, circumcentre of (x, c, a)
        closing = ~in_cavity(after)
        leave = _circumcentre(x[closing], points[a[closing]], points[c[closing]])
        term[closing] += _cross(c_t[closing] - origin[closing], leave - origin[closing])
        numerator += np.bincount(query, term * values[a], minlength=len(xy))
        area += np.bincount(query, term, minlength=len(xy))
    with np.errstate(divide="ignore", invalid="ignore"):
        field = numerator / area
    ok = np.isfinite(field) & (np.abs(area) > 0)
    return np.where(ok, field, fallback)


def _cavities(xy, simplex, across, centre, radius2):
    """Every (query, triangle) pair whose circumcircle strictly holds the query, found by
    growing each query's cavity from its own triangle through neighbours: (query indices,
    triangle indices, their sorted keys query * triangles + triangle)."""
    n_triangles = len(centre)

    def inside_circle(q, t):  # strictly: a query on a cell lies on its triangles' circles and keeps `fallback`
        return ((xy[q] - centre[t]) ** 2).sum(-1) < radius2[t] * (1 - 1e-9)

    query = np.arange(len(xy))
    keep = inside_circle(query, simplex)
    frontier = query[keep] * n_triangles + simplex[keep]
    keys = np.sort(frontier)
    while frontier.size:
        q, t = np.divmod(frontier, n_triangles)
        q, t = np.repeat(q, 3), across[t].ravel()
        q, t = q[t >= 0], t[t >= 0]
        hit = inside_circle(q, t)
        candidates = _sorted_unique(q[hit] * n_triangles + t[hit])
        frontier = candidates[~_members(candidates, keys)]
        keys = np.sort(np.concatenate([keys, frontier]))
    query, triangle = np.divmod(keys, n_triangles)
    return query, triangle, keys


def _sorted_unique(keys) -> np.ndarray:
    """The distinct `keys`, sorted (np.unique's hashing is slower on these integer keys)."""
    keys = np.sort(keys)
    return keys[np.r_[True, keys[1:] != keys[:-1]]] if keys.size else keys


def _members(keys, sorted_keys) -> np.ndarray:
    """Whether each of `keys` is in `sorted_keys` (a sorted array)."""
    if not sorted_keys.size:
        return np.zeros(keys.shape, bool)
    found = np.minimum(np.searchsorted(sorted_keys, keys), sorted_keys.size - 1)
    return sorted_keys[found] == keys


# ---- SVG -----------------------------------------------------------------------------------
def write_cells_svg(cells: Cells, path, reagent=None, *, cmap="inferno", vmin=None, vmax=None, polarity: bool = False,
                    polarity_colour="white", background=None, margin: float = 1.0) -> Path:
    """Write the live cells as SVG (thesis 4.6's vector export): one `<circle>` of radius 1
    per live cell, filled with its colour (as `render_cells`), in cell radii with y flipped
    so +y is up, the viewBox framing the cells' discs plus `margin`. `polarity` adds a
    `<line>` from each polarised cell's centre to its rim; `background` (a colour, default
    none) fills the view. Written atomically: a crash never leaves a broken file in place
    of an earlier one. Returns the path."""
    check_range(margin, "margin", low=0.0)
    live, values = _live(cells, reagent, "write_cells_svg")
    position = live["position"]
    colours = _colours(values, cmap, *_value_range(values, vmin, vmax))
    low, high = _box(position, CELL_RADIUS + float(margin))
    width, height = high - low
    lines = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="{_n(low[0])} {_n(-high[1])} {_n(width)} {_n(height)}" '
        f'width="{_n(width * SVG_SCALE)}" height="{_n(height * SVG_SCALE)}">',
    ]
    if background is not None:
        lines.append(f'<rect x="{_n(low[0])}" y="{_n(-high[1])}" width="{_n(width)}" height="{_n(height)}" '
                     f'fill="{_hex(_rgb(background))}"/>')
    lines += [f'<circle cx="{_n(x)}" cy="{_n(-y)}" r="{_n(CELL_RADIUS)}" fill="{_hex(rgb)}"/>'
              for (x, y), rgb in zip(position.tolist(), colours.tolist())]
    if polarity:
        stroke = _hex(_rgb(polarity_colour))
        angle, polarised = live["polarity"][live["polarised"]], live["polarised"]
        tips = position[polarised] + POLARITY_LENGTH * np.stack([np.cos(angle), np.sin(angle)], axis=-1)
        lines += [f'<line x1="{_n(x0)}" y1="{_n(-y0)}" x2="{_n(x1)}" y2="{_n(-y1)}" stroke="{stroke}" '
                  f'stroke-width="{_n(POLARITY_STROKE)}"/>' for (x0, y0), (x1, y1) in zip(position[polarised].tolist(), tips.tolist())]
    lines.append("</svg>")
    text = "\n".join(lines) + "\n"
    return write_atomically(path, lambda temporary: Path(temporary).write_text(text, encoding="utf-8"))


def _n(value: float) -> str:
    return f"{float(value):.9g}"


def _hex(rgb) -> str:
    return "#{:02x}{:02x}{:02x}".format(*(int(v) for v in rgb))


__all__ = ["cells_field", "render_cells", "cells_texture", "texture_pixel_centres", "write_cells_svg"]
