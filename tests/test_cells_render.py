"""Pictures of off-lattice cells (thesis 4.6-4.7): discs, Voronoi tiles, interpolated
textures and SVG, against NumPy oracles written from the documented geometry."""

import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from scipy.spatial import Delaunay, cKDTree

from morphojax._render import colormap_table
from morphojax.cells import cell_grid, make_cells
from morphojax.cells._render import (
    cells_field,
    render_cells,
    cells_texture,
    texture_pixel_centres,
    write_cells_svg,
)

SVG = "{http://www.w3.org/2000/svg}"


def _grid(values=None, shape=(5, 7), capacity=None, species=("u", "v"), **fill):
    """A square grid (centres 2 apart, x in -6..6 and y in -4..4 for 5 x 7) whose first
    reagent is `values(x, y)` and second its negative."""
    xy = cell_grid(shape, species).live()["position"].astype(float)
    u = values(xy[:, 0], xy[:, 1]) if values else np.arange(len(xy), dtype=float)
    return make_cells(species, xy, concentration=np.stack([u, -u]), capacity=capacity, **fill), xy, u


def _oracle_colours(values, cmap, vmin=None, vmax=None):
    """The colour map of the min-max normalised values, rounded to the table's 256 entries."""
    lo = values.min() if vmin is None else vmin
    hi = values.max() if vmax is None else vmax
    t = np.clip((values - lo) / (hi - lo), 0, 1)
    return colormap_table(cmap)[np.round(t * 255).astype(int)]


def _fitted_pixel(xy, low, high, width, height):
    """(row, col) of the pixel holding each world point: the box [low, high] fitted into the
    image keeping its aspect ratio, centred, +y up."""
    scale = min(width / (high[0] - low[0]), height / (high[1] - low[1]))
    centre = (np.asarray(low) + np.asarray(high)) / 2
    col = np.floor((xy[:, 0] - centre[0]) * scale + width / 2).astype(int)
    row = np.floor(height / 2 - (xy[:, 1] - centre[1]) * scale).astype(int)
    return row, col


def _brute_nearest(points, queries):
    d = ((queries[:, None, :] - points[None, :, :]) ** 2).sum(-1)
    return d.argmin(1), np.sqrt(d.min(1))


# ---- discs and Voronoi tiles -------------------------------------------------------------
def test_disc_colours_at_cell_centres_follow_the_colour_map():
    cells, xy, u = _grid(lambda x, y: np.sin(x) + 0.3 * y)
    image = np.asarray(render_cells(cells, size=160, cmap="viridis"))
    assert image.shape == (120, 160, 3)  # box 16 x 12 cell radii (centres +- radius + margin)
    row, col = _fitted_pixel(xy, (-8, -6), (8, 6), 160, 120)
    np.testing.assert_array_equal(image[row, col], _oracle_colours(u, "viridis"))
    # a fixed range and the second reagent, by name
    image = np.asarray(render_cells(cells, "v", size=160, cmap="gray", vmin=-1.0, vmax=0.5))
    np.testing.assert_array_equal(image[row, col], _oracle_colours(-u, "gray", -1.0, 0.5))


def test_between_cells_discs_leave_background_and_voronoi_fills_from_the_nearest_cell():
    cells, xy, u = _grid()
    size = 320  # 20 pixels per cell radius
    # points among four cells (more than one cell radius from each, less than 1.5)
    probes = np.array([[1.2, 1.1], [-4.9, -2.8], [3.1, -1.2]])
    near, distance = _brute_nearest(xy, probes)
    assert (distance > 1.05).all() and (distance < 1.45).all()
    row, col = _fitted_pixel(probes, (-8, -6), (8, 6), 320, 240)
    discs = np.asarray(render_cells(cells, size=size, background=(0, 0, 255)))
    np.testing.assert_array_equal(discs[row, col], [[0, 0, 255]] * 3)
    voronoi = np.asarray(render_cells(cells, size=size, style="voronoi", background=(0, 0, 255)))
    np.testing.assert_array_equal(voronoi[row, col], _oracle_colours(u, "inferno")[near])
    # far from every cell (the margin) both stay background
    assert (discs[:5] == [0, 0, 255]).all() and (voronoi[:5] == [0, 0, 255]).all()


def test_every_pixel_takes_its_nearest_cell_within_reach():
    """The whole image against a brute-force oracle, both styles (reach 1 and 1.5)."""
    jitter = np.random.default_rng(3).uniform(-0.3, 0.3, (20, 2))
    xy = cell_grid((4, 5), "u").live()["position"] + jitter
    u = np.linspace(0.0, 1.0, 20)
    cells = make_cells(("u",), xy, concentration=u[None])
    xy = cells.live()["position"].astype(float)
    low, high = xy.min(0) - 2.0, xy.max(0) + 2.0
    width = 90
    height = round(width * (high[1] - low[1]) / (high[0] - low[0]))
    scale, centre = width / (high[0] - low[0]), (low + high) / 2
    px = centre[0] + (np.arange(width) + 0.5 - width / 2) / scale
    py = centre[1] - (np.arange(height) + 0.5 - height / 2) / scale
    pixels = np.stack(np.meshgrid(px, py), -1).reshape(-1, 2)
    near, distance = _brute_nearest(xy, pixels)
    colours = _oracle_colours(u, "inferno")
    for style, reach in (("discs", 1.0), ("voronoi", 1.5)):
        image = np.asarray(render_cells(cells, size=width, style=style)).reshape(-1, 3)
        expected = np.where((distance <= reach)[:, None], colours[near], 0)
        clear = np.abs(distance - reach) > 1e-6  # leave pixels exactly at the reach alone
        np.testing.assert_array_equal(image[clear], expected[clear])


def test_y_points_up():
    """The cell with the largest value sits at the top (largest y): it lands in the top rows."""
    cells, xy, u = _grid(lambda x, y: np.where(y == y.max(), 1.0, 0.0) + 0 * x)
    image = np.asarray(render_cells(cells, size=160, cmap="gray"))
    bright = np.argwhere((image == 255).all(-1))
    assert bright[:, 0].max() < 40  # the top third of 120 rows
    top, bottom = image[: 60], image[60:]
    assert (top == 255).all(-1).sum() > 0 and (bottom == 255).all(-1).sum() == 0
    field = cells_field(cells, size=(7, 5))
    np.testing.assert_array_equal(field[0], 1.0)
    np.testing.assert_array_equal(field[1:], 0.0)


def test_aspect_ratio_is_kept():
    cells, xy, _ = _grid()  # box 16 x 12 cell radii
    assert render_cells(cells, size=100).size == (100, 75)
    assert render_cells(cells, size=100, margin=0.0).size == (100, 71)  # 14 x 10: 100 x 71.4
    tall, _, _ = _grid(shape=(7, 3))  # box 8 x 16
    assert render_cells(tall, size=160).size == (80, 160)
    # a wide frame letterboxes the same picture: 10 pixels per cell radius both ways
    snug = np.asarray(render_cells(cells, size=160, background="white"))
    wide = np.asarray(render_cells(cells, size=(400, 120), background="white"))
    assert wide.shape == (120, 400, 3)
    np.testing.assert_array_equal(wide[:, 120:280], snug)
    assert (wide[:, :120] == 255).all() and (wide[:, 280:] == 255).all()


def test_dead_cells_are_not_drawn():
    cells, _, _ = _grid()
    roomy, _, _ = _grid(capacity=60)  # 25 unused entries at the origin, concentration 0
    for style in ("discs", "voronoi"):
        np.testing.assert_array_equal(np.asarray(render_cells(cells, size=64, style=style)),
                                      np.asarray(render_cells(roomy, size=64, style=style)))
    np.testing.assert_array_equal(cells_field(cells, size=40), cells_field(roomy, size=40))


def test_polarity_segments_point_along_the_angle_with_y_up():
    xy = np.array([[0.0, 0.0], [6.0, 0.0]])
    cells = make_cells(("u",), xy, concentration=[[0.0, 0.0]], polarity=[math.pi / 2, np.nan])
    image = np.asarray(render_cells(cells, size=(200, 100), polarity=True, polarity_colour=(0, 255, 0), margin=0.0))
    green = (image == [0, 255, 0]).all(-1)
    # the box x in [-1, 7], y in [-1, 1] fills 200 x 50 of 200 x 100: 25 pixels per cell radius
    row, col = _fitted_pixel(xy, (-1, -1), (7, 1), 200, 100)
    assert green[row[0] - 22:row[0], col[0]].all()  # up the image, from the centre to the rim
    assert not green[row[0] + 3:, :].any() and not green[:row[0] - 28, :].any()
    assert not green[:, col[0] + 6:].any()  # the unpolarised cell has no segment
    plain = np.asarray(render_cells(cells, size=(200, 100), margin=0.0))
    assert not (plain == [0, 255, 0]).all(-1).any()


# ---- interpolated textures -----------------------------------------------------------------
def test_texture_pixel_centres_cover_the_box_grown_by_a_radius():
    cells, xy, _ = _grid()
    centres = texture_pixel_centres(cells, (21, 15))  # box 14 x 10: pixels 2/3 apart
    assert centres.shape == (15, 21, 2)
    np.testing.assert_allclose(centres[0, 0], [-7 + 1 / 3, 5 - 1 / 3])
    np.testing.assert_allclose(centres[-1, -1], [7 - 1 / 3, -5 + 1 / 3])
    np.testing.assert_allclose(np.diff(centres[0, :, 0]), 2 / 3)
    np.testing.assert_allclose(np.diff(centres[:, 0, 1]), -2 / 3)
    assert texture_pixel_centres(cells, 70).shape == (50, 70, 2)  # aspect ratio kept


@pytest.mark.parametrize("method", ["linear", "natural"])
def test_interpolation_reproduces_a_linear_function_and_the_cell_values(method):
    cells, xy, u = _grid(lambda x, y: 2 * x + 3 * y)
    centres = texture_pixel_centres(cells, (21, 15))
    field = cells_field(cells, size=(21, 15), method=method)
    x, y = centres[..., 0], centres[..., 1]
    hull = (np.abs(x) <= 6) & (np.abs(y) <= 4)
    np.testing.assert_allclose(field[hull], (2 * x + 3 * y)[hull], rtol=0, atol=1e-12)
    # every third pixel sits on a cell centre: there the field is the cell's value
    at_cell = np.isclose((x + 6) / 2, np.round((x + 6) / 2)) & np.isclose((y + 4) / 2, np.round((y + 4) / 2)) & hull
    assert at_cell.sum() == 35
    near, _ = _brute_nearest(xy, centres[at_cell])
    np.testing.assert_array_equal(field[at_cell], u[near])
    # outside the convex hull every pixel takes its nearest cell's value
    near, _ = _brute_nearest(xy, centres[~hull])
    assert not np.isclose(field[~hull], (2 * x + 3 * y)[~hull]).all()
    for q, f in zip(centres[~hull], field[~hull]):
        d = np.hypot(*(xy - q).T)
        assert f in u[np.isclose(d, d.min())]  # ties between equidistant cells go either way


@pytest.mark.parametrize("method", ["linear", "natural"])
def test_scattered_cells_reproduce_a_linear_function(method):
    rng = np.random.default_rng(7)
    xy = rng.uniform(-6.0, 6.0, (40, 2))
    cells = make_cells(("u",), xy, concentration=(2 * xy[:, 0] + 3 * xy[:, 1])[None])
    xy = cells.live()["position"].astype(float)
    u = cells.live()["concentration"][0].astype(float)
    assert np.abs(u - (2 * xy[:, 0] + 3 * xy[:, 1])).max() < 1e-5  # float32 storage
    field = cells_field(cells, size=64, method=method)
    centres = texture_pixel_centres(cells, 64)
    inside = Delaunay(xy).find_simplex(centres.reshape(-1, 2)).reshape(field.shape) >= 0
    assert inside.mean() > 0.5
    np.testing.assert_allclose(field[inside], (2 * centres[..., 0] + 3 * centres[..., 1])[inside], atol=1e-4)


def test_natural_neighbour_weights_are_the_stolen_voronoi_areas():
    """Sibson's interpolant (thesis 4.6, CGAL's natural neighbours) against a brute-force
    oracle: sample a fine grid, find which points the query's new Voronoi cell takes and from
    which cell, and weight the cells' values by those counts."""
    rng = np.random.default_rng(11)
    xy = cell_grid((4, 4), "u").live()["position"] + rng.uniform(-0.5, 0.5, (16, 2))
    cells = make_cells(("u",), xy, concentration=np.sin(xy[:, 0])[None] * xy[:, 1])
    xy = cells.live()["position"].astype(float)
    u = cells.live()["concentration"][0].astype(float)
    size = (9, 8)
    natural = cells_field(cells, size=size, method="natural")
    linear = cells_field(cells, size=size, method="linear")
    centres = texture_pixel_centres(cells, size)
    inside = Delaunay(xy).find_simplex(centres.reshape(-1, 2)).reshape(natural.shape) >= 0
    h, edge = 0.03, 12.0
    fine = np.mgrid[-edge:edge:h, -edge:edge:h].reshape(2, -1).T
    rim = (np.abs(fine) > edge - 2 * h).any(1)
    distance, owner = cKDTree(xy).query(fine)
    checked, differs = 0, 0
    for (i, j) in np.argwhere(inside)[::2]:
        q = centres[i, j]
        stolen = np.hypot(*(fine - q).T) < distance
        if stolen.sum() < 200 or stolen[rim].any():  # too small to resolve, or beyond the window
            continue
        weights = np.bincount(owner[stolen], minlength=len(xy))
        expected = (weights * u).sum() / weights.sum()
        assert abs(natural[i, j] - expected) < 0.01, (q, natural[i, j], expected)
        checked += 1
        differs += abs(linear[i, j] - expected) > 0.03
    assert checked >= 8 and differs >= 2  # and the oracle tells natural from linear


def test_nearest_method_and_collinear_cells():
    cells, xy, u = _grid(lambda x, y: x * y + x)
    centres = texture_pixel_centres(cells, 30).reshape(-1, 2)
    field = cells_field(cells, size=30, method="nearest").ravel()
    for q, f in zip(centres, field):
        d = np.hypot(*(xy - q).T)
        assert f in u[np.isclose(d, d.min())]
    # one row of cells spans no area: every method falls back to the nearest cell
    row, xy, u = _grid(lambda x, y: x ** 2, shape=(1, 5))
    fields = [cells_field(row, size=(20, 4), method=m) for m in ("linear", "natural", "nearest")]
    np.testing.assert_array_equal(fields[0], fields[2])
    np.testing.assert_array_equal(fields[1], fields[2])
    single = make_cells(("u",), [[1.0, 2.0]], concentration=[[3.0]])
    np.testing.assert_array_equal(cells_field(single, size=5, method="natural"), 3.0)


def test_texture_colours_match_the_discs():
    cells, xy, u = _grid(lambda x, y: np.cos(x) * y)
    texture = np.asarray(cells_texture(cells, size=(21, 15), cmap="viridis"))
    field = cells_field(cells, size=(21, 15))
    lo, hi = u.min(), u.max()
    expected = colormap_table("viridis")[np.round(np.clip((field - lo) / (hi - lo), 0, 1) * 255).astype(int)]
    np.testing.assert_array_equal(texture, expected)
    fixed = np.asarray(cells_texture(cells, size=(21, 15), cmap="gray", vmin=0.0, vmax=1.0, method="natural"))
    natural = cells_field(cells, size=(21, 15), method="natural")
    np.testing.assert_array_equal(fixed[..., 0], np.round(np.clip(natural, 0, 1) * 255).astype(np.uint8))


# ---- SVG -----------------------------------------------------------------------------------
def test_svg_has_one_circle_per_live_cell_with_its_colour(tmp_path):
    cells, xy, u = _grid(lambda x, y: x - y, capacity=50, polarity=np.where(np.arange(35) % 2, 0.3, np.nan))
    path = write_cells_svg(cells, tmp_path / "cells.svg", cmap="viridis", polarity=True)
    root = ET.parse(path).getroot()
    circles = root.findall(f"{SVG}circle")
    assert len(circles) == 35  # the 15 unused entries are not cells
    centre = np.array([[float(c.get("cx")), float(c.get("cy"))] for c in circles])
    np.testing.assert_allclose(centre, xy * [1, -1])  # +y up: SVG's y runs down
    assert {c.get("r") for c in circles} == {"1"}
    fills = ["#%02x%02x%02x" % tuple(rgb) for rgb in _oracle_colours(u, "viridis")]
    assert [c.get("fill") for c in circles] == fills
    x0, y0, w, h = (float(v) for v in root.get("viewBox").split())
    np.testing.assert_allclose([x0, y0, w, h], [-8, -6, 16, 12])  # discs plus a margin of 1
    lines = root.findall(f"{SVG}line")
    assert len(lines) == 17
    first = lines[0]
    start = np.array([float(first.get("x1")), float(first.get("y1"))])
    end = np.array([float(first.get("x2")), float(first.get("y2"))])
    np.testing.assert_allclose(start, xy[1] * [1, -1])
    np.testing.assert_allclose(end - start, [math.cos(0.3), -math.sin(0.3)], atol=1e-6)
    assert not ET.parse(write_cells_svg(cells, path)).getroot().findall(f"{SVG}line")


def test_svg_replaces_the_file_whole_and_leaves_no_temporaries(tmp_path):
    cells, _, _ = _grid()
    path = tmp_path / "out.svg"
    path.write_text("earlier")
    with pytest.raises(ValueError, match="reagent"):
        write_cells_svg(cells, path, "w")
    assert path.read_text() == "earlier"
    write_cells_svg(cells, path, background="white")
    root = ET.parse(path).getroot()
    assert root.find(f"{SVG}rect").get("fill") == "#ffffff"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.svg"]


# ---- errors ----------------------------------------------------------------------------------
def test_errors_name_the_parameter_and_the_allowed_values(tmp_path):
    cells, _, _ = _grid()
    with pytest.raises(ValueError, match=r"unknown reagent 'w'; the cells carry u, v"):
        render_cells(cells, "w")
    with pytest.raises(ValueError, match=r"reagent must be one of u, v or an index in \[0, 1\]"):
        cells_field(cells, 2)
    with pytest.raises(ValueError, match="reagent must be"):
        render_cells(cells, True)
    empty = make_cells(("u",), np.zeros((0, 2)), capacity=4)
    for draw in (render_cells, cells_field, cells_texture):
        with pytest.raises(ValueError, match="at least one live cell"):
            draw(empty)
    with pytest.raises(ValueError, match="at least one live cell"):
        write_cells_svg(empty, tmp_path / "x.svg")
    for size in (0, -3, 20000, (10,), (10, 0), (10, 2.5), True, 12.0, "big"):
        with pytest.raises(ValueError, match=r"size must be .* in \[1, 16384\]"):
            render_cells(cells, size=size)
        with pytest.raises(ValueError, match="size must be"):
            cells_field(cells, size=size)
    with pytest.raises(ValueError, match=r"unknown style 'hex'; allowed: 'discs', 'voronoi'"):
        render_cells(cells, style="hex")
    with pytest.raises(ValueError, match=r"unknown method 'cubic'; allowed: 'linear', 'nearest', 'natural'"):
        cells_texture(cells, method="cubic")
    with pytest.raises(ValueError, match=r"margin must lie in \[0"):
        render_cells(cells, margin=-1.0)
    with pytest.raises(ValueError, match="unknown colour map"):
        render_cells(cells, cmap="rainbow")
    with pytest.raises(ValueError, match="vmax must be >= vmin"):
        cells_texture(cells, vmin=2.0, vmax=1.0)
    with pytest.raises(ValueError, match="unknown colour"):
        render_cells(cells, background="no-such-colour")
    with pytest.raises(ValueError, match="texture_pixel_centres needs"):
        texture_pixel_centres(np.zeros((0, 2)))
