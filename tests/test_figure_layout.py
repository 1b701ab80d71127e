"""The montage of a figure made of several presets (`morphojax run thesis-fig5.10`): tiles of
one size and the figure's own labels (issue 38's rendering bug: an 80 px square tile beside a
648 px hexagonal one, labelled "square" twice)."""

import numpy as np
from PIL import Image

import morphojax as mj
from morphojax.cli._run import figure_layout


def _tiles():
    # what render_experiment draws for the 40 x 40 members at --scale 2: the square lattice
    # 2 pixels per cell, the hexagonal one 16 pixels per hexagon
    square = mj.to_image(np.random.default_rng(0).random((40, 40)), scale=2)
    hexagonal = mj.hex_image(np.random.default_rng(1).random((40, 40)), scale=16)
    return square, hexagonal


def test_fig5_10_tiles_have_one_width_and_the_figure_labels():
    item = mj.PRESETS["thesis-fig5.10"]
    square, hexagonal = _tiles()
    assert (square.width, hexagonal.width) == (80, 648)  # the sizes the bug report gives
    images, ncols, row_labels = figure_layout(item, [[square], [hexagonal]])
    assert ncols == 2 and len(images) == 2
    assert images[0].width == images[1].width == 648
    assert images[0].height == 648  # the square lattice stays square, enlarged 8.1 times
    assert row_labels is None  # one row of tiles: the column labels say which is which
    labels = list(item.col_labels) + list(row_labels or [])
    assert labels.count("square") == 1 and "hexagonal" in labels


def test_rows_of_snapshots_keep_their_member_labels():
    tile = Image.new("RGB", (10, 10))
    fake = type("Figure", (), {"members": ("a-top", "b-bottom"), "row_labels": None, "col_labels": None,
                               "snapshots": True})()
    images, ncols, row_labels = figure_layout(fake, [[tile, tile], [tile]])
    assert ncols == 2 and len(images) == 4 and row_labels == ["top", "bottom"]
