"""The reader of the thesis's experiment language (thesis 4.8, Appendix A): every shipped
listing parses and round-trips, concrete parses against the printed numbers, prepattern
numbering against the thesis's cell indices, errors naming their line, and a tiny run."""

import hashlib
import math

import jax
import numpy as np
import pytest

from morphojax._status import SimulationError
from morphojax import Bard, Gradient
from morphojax.cells import AGE, NEIGHBORS, Always, Box, Chance, Change, Compare, Divide, Map, Packed, Polarize, React, Within
from morphojax.cells import conc, diff, mapped
from morphojax.cells._listing import LISTING_DIR, LISTINGS, listing_path, load_listing
from morphojax.cells._listing_commands import Create, SetCells, Snap, UseChemical, UsePolarity
from morphojax.cells._listing_write import rule_key, same_rules

SHIPPED = sorted(LISTING_DIR.glob("*.txt"))


def values(leaf) -> np.ndarray:
    return np.asarray(leaf, float)


def hex_oracle(rows, cols):
    """Hexagonal grid centres, row by row from the lowest row, odd rows shifted +x by
    half a spacing, rows sqrt(3) apart (spacing 2), centred on the origin."""
    r, c = np.divmod(np.arange(rows * cols), cols)
    xy = np.stack([2.0 * c + (r % 2), math.sqrt(3) * r], axis=1)
    return xy - (xy.min(axis=0) + xy.max(axis=0)) / 2


# ---- every shipped listing -----------------------------------------------------------


# sha256 (first 16 hex digits) of every shipped listing, pinned when the files were cut
# from the thesis's text and compared with it line by line: they must stay verbatim (the
# presets, not the files, make the corrections a listing needs)
CHECKSUMS = {
    "A01_fig5.14.txt": "7e5dd8d8643988da",
    "A02_fig5.15.txt": "08c538b77592e29a",
    "A03_fig6.1.txt": "92b3b82e20f5a44e",
    "A04_fig6.2.txt": "3993a71b07422d69",
    "A05_fig6.3.txt": "78d8a9b472bd568f",
    "A06_fig6.4.txt": "e4e18eac127450dd",
    "A07_fig6.5.txt": "4f633278ffa72782",
    "A08_fig6.6.txt": "f040cdcd95983024",
    "A09_fig6.7.txt": "287871fce0ba75e9",
    "A10_fig6.8.txt": "0fb6aae919847687",
    "A11_fig6.10.txt": "2bba4e000a156d17",
    "A12_fig7.2.txt": "6d070435f567ee75",
    "A13_fig7.3.txt": "0f9a4eda71d1728a",
    "A14_fig7.7.txt": "c4438458ce34adf9",
    "A15_fig7.8.txt": "6ca37ea2f0d7c49e",
    "A16_fig7.16.txt": "5e630c6f5d397252",
    "A17_fig7.18.txt": "e31e41e33a320816",
    "A18_fig7.21.txt": "63768caabe3dd839",
    "fig5.1.txt": "5841456ff4dee88c",
    "fig5.2.txt": "a7306a23347f6660",
    "fig7.13.txt": "e2fc466c19b15730",
    "fig7.15.txt": "33a30aca0b1eee68",
    "fig7.20.txt": "437b5ac3c855bf81",
    "listing4.1.txt": "f48c035b3daaef1a",
    "listing5.1.txt": "a4fe8e82b650c350",
}


def test_the_shipped_files_are_the_thesis_listings():
    names = {p.name for p in SHIPPED}
    assert names == set(CHECKSUMS)
    for path in SHIPPED:
        assert hashlib.sha256(path.read_bytes()).hexdigest()[:16] == CHECKSUMS[path.name], path.name
    assert LISTINGS["A.18"] == LISTINGS["fig7.21"] == listing_path("Fig 7.21") == listing_path("A18_fig7.21")
    assert listing_path("a.3").name == "A03_fig6.1.txt" and listing_path("listing4.1").name == "listing4.1.txt"
    assert all(path.is_file() for path in LISTINGS.values())
    with pytest.raises(ValueError, match="unknown listing 'A.19'"):
        listing_path("A.19")
    assert load_listing("A.18").name == "A18_fig7.21"
    with pytest.raises(ValueError, match="no listing file 'missing.txt'"):
        load_listing("missing.txt")


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.stem)
def test_every_shipped_listing_parses_and_round_trips(path):
    listing = load_listing(path)
    text = listing.to_text()
    again = load_listing(text)
    assert again == listing
    assert again.to_text() == text  # canonical: writing is idempotent
    assert "//" not in text and listing.name == path.stem
    assert again.warnings == () or path.stem.startswith("A17")


def test_round_trip_is_not_vacuous():
    a18 = load_listing("A.18")
    assert a18 != load_listing(a18.to_text().replace("scale 0.025", "scale 0.026"))
    assert a18 != load_listing(a18.to_text().replace("set cell 640 chemical V conc 10\n", ""))
    assert a18 != load_listing(a18.to_text().replace("define domain packed", "define domain packed area 3"))
    assert not same_rules(a18.rules, a18.rules[:1])


# ---- concrete parses -----------------------------------------------------------------


def test_listing_4_1_react_is_bard_with_the_listing_numbers():
    listing = load_listing("listing4.1")
    assert listing.species == ("U", "V") and listing.dt == 1.0 and listing.steps == 10000 and listing.seed is None
    assert listing.commands == (UseChemical("U", (4.0, 2.0), (0.04, 0.0)), UseChemical("V", (4.0, 2.0), (0.01, 0.0)),
                                Create("sqr_grid", (100, 100)))
    (rule,) = listing.rules
    assert isinstance(rule.when[0], Always) and rule.start is None and rule.stop is None
    react = rule.action
    assert isinstance(react, React) and react.species == ("U", "V") and isinstance(react.model, Bard)
    assert [float(react.model.alpha), float(react.model.beta), float(react.model.sp)] == [16.0, 12.0, 1.0]
    assert float(react.scale) == pytest.approx(0.01)
    # Bard's reaction is sp (alpha - a b), sp (a b - b - beta) on (U, V)
    np.testing.assert_allclose(values(react.model.reaction(np.array([2.0, 3.0]))), [16 - 6, 6 - 3 - 12])


def test_a18_numbers():
    listing = load_listing("A.18")
    assert [(c.name, c.limit, c.anisotropic) for c in listing.chemicals] == [("U", 4.05, False), ("V", None, False)]
    assert listing.dt == 0.1 and listing.division_limit == 6 and listing.steps == 14000
    assert isinstance(listing.domain, Packed) and float(listing.domain.area) == pytest.approx(3.2)
    assert listing.texture == (512, 512) and listing.zoom == 1.503
    react, divide = listing.rules
    assert float(react.action.scale) == pytest.approx(0.025)
    assert isinstance(divide.action, Divide) and divide.start == 4000 and divide.stop is None
    assert float(divide.action.spread) == pytest.approx(math.pi) and float(divide.action.direction) == 0.0
    assert float(divide.when[0].probability) == pytest.approx(1e-4)

    cells = listing.prepattern(jax.random.key(0))
    assert int(cells.count) == 2900 == 50 * 58  # `create hex_grid 50 58`: 50 columns, 58 rows
    np.testing.assert_allclose(values(cells.position), hex_oracle(58, 50), atol=1e-4)
    seeds = [205, 215, 225, 235, 245, 610, 620, 630, 640]
    v = values(cells["V"])
    assert sorted(np.flatnonzero(v == 10.0).tolist()) == seeds
    assert np.all(np.delete(v, seeds) == 4.0) and np.all(values(cells["U"]) == 4.0)  # dev 0
    # the seeds lie on rows 4 and 12, every 10 columns: the published lattice of spots
    assert [divmod(i, 50) for i in seeds] == [(4, 5), (4, 15), (4, 25), (4, 35), (4, 45),
                                              (12, 10), (12, 20), (12, 30), (12, 40)]
    np.testing.assert_allclose(values(cells.diffusion[:, 0]), [0.40, 0.01], rtol=1e-6)
    assert values(cells.upper)[0] == pytest.approx(4.05) and math.isinf(values(cells.upper)[1])


def test_a11_map_windows_and_reinforcement():
    listing = load_listing("A.11")
    assert listing.species == ("R", "V", "U") and listing.division_limit == 6
    assert listing.commands[2] == UseChemical("R", (0.0, 0.0), (0.0004, 0.0))
    assert listing.commands[3] == Create("hex_circle", (45.0,))
    react, copy, paste, down, up, divide = listing.rules
    assert isinstance(copy.action, Map) and (copy.start, copy.stop) == (1999, 1999)
    m = copy.action
    assert m.source == conc("V") and m.name == "PAT"
    assert [float(m.low), float(m.high), float(m.out_low), float(m.out_high)] == [1.0, 7.0, 0.0, 2.0]
    assert isinstance(paste.action, Change) and paste.action.target == conc("R") and paste.action.amount == mapped("PAT")
    assert (paste.start, paste.stop) == (1999, 1999)
    for rule, (low, high, amount) in ((down, (0.1, 0.9, -0.0004)), (up, (1.1, 1.9, 0.0004))):  # `+0.0004`
        (within,) = rule.when
        assert isinstance(within, Within) and within.value == conc("R") and rule.start == 1999 and rule.stop is None
        np.testing.assert_allclose([float(within.low), float(within.high), float(rule.action.amount)], [low, high, amount])
    assert (divide.start, divide.stop) == (2000, 15000)
    assert listing.snaps == (Snap((2000, 6000, 9000, 12000, 15000), exit=True),) and listing.steps == 15000


def test_and_chains_become_one_rule():
    a13 = load_listing("A.13")
    chain = a13.rules[3]
    first, chance, window = chain.when
    assert isinstance(first, Compare) and first.left == conc("C") and first.op == "==" and float(first.right) == 1.0
    assert isinstance(chance, Chance) and chance.probability == conc("G")  # `probability G conc`
    assert isinstance(window, Within) and window.value == conc("P")
    assert isinstance(chain.action, Change) and float(chain.action.amount) == 2.0
    assert len(a13.rules) == 7 and a13.chemicals[0].limit == 1.0

    a12 = load_listing("A.12")
    assert len(a12.rules) == 8 and [len(r.when) for r in a12.rules] == [1, 1, 1, 2, 1, 2, 2, 3]
    last = a12.rules[-1]
    assert [c.left for c in last.when[:2]] == [conc("C"), conc("S")] and last.when[2].value == conc("N")

    a8 = load_listing("A.8")
    directions = [math.degrees(float(r.action.direction)) for r in a8.rules[1:]]
    np.testing.assert_allclose(directions, [0, 20, -20], atol=1e-5)
    assert all(r.when[0].left == NEIGHBORS and r.when[0].op == "<=" for r in a8.rules[1:])


def test_divide_and_age_conditions_in_degrees():
    a3 = load_listing("A.3")
    assert a3.rules[0].when[0].left == AGE and isinstance(a3.rules[0].action, Divide)
    assert a3.commands[2] == UsePolarity(-90.0) and a3.commands[3] == Create("sqr_grid", (80, 1))
    assert float(load_listing("A.5").rules[1].action.direction) == pytest.approx(math.radians(137.5))
    a6 = load_listing("A.6")
    assert [float(r.action.direction) for r in a6.rules[2:]] == pytest.approx([math.pi / 2, -math.pi / 2])
    assert a6.commands[-1] == Create("sqr_grid", (40, 1), fixed=True) and a6.steps == 16000  # the snap is a comment
    assert isinstance(load_listing("A.1").rules[2].action, Polarize)
    a4 = load_listing("A.4")
    assert isinstance(a4.domain, Box) and (float(a4.domain.width), float(a4.domain.height)) == (200.0, 200.0)
    assert a4.commands[-1] == Create("sqr_grid", (1, 25), dev=0.1)


def test_numbers_and_comments():
    listing = load_listing("define chemical R // a comment\n"
                           "use chemical R conc 00 diff +0.0004 dev 1e-5   // diff with dev\n"
                           "create sqr_grid 2 2 at -1.5 .5\n"
                           "rule from 00 if R conc >= -.25 change R conc -1E-3 // done")
    assert listing.commands == (UseChemical("R", (0.0, 0.0), (0.0004, 1e-5)), Create("sqr_grid", (2, 2), at=(-1.5, 0.5)))
    rule = listing.rules[0]
    assert rule.start == 0 and float(rule.when[0].right) == -0.25 and float(rule.action.amount) == pytest.approx(-1e-3)


def test_empty_window_and_uneven_chain_are_read_as_written_with_warnings():
    a17 = load_listing("A.17")
    assert a17.warnings == ("line 32: the window from 2500 until 2000 is empty; this rule never fires",)
    never = a17.rules[1]
    assert (never.start, never.stop) == (2500, 2000) and never.action.target == diff("P")

    text = ("define chemical R\ncreate cell 0 0\n"
            "rule from 100 if R conc > 1 and\n"
            "rule until 50 always change R conc 1\n")
    listing = load_listing(text)
    (rule,) = listing.rules
    assert (rule.start, rule.stop) == (100, 50) and len(rule.when) == 2
    assert listing.warnings == (
        "lines 3-4: the 'and' chain joins rules with different windows (line 3: from 100; line 4: until 50); "
        "the rule runs on their intersection, from 100 until 50",
        "line 4: the window from 100 until 50 is empty; this rule never fires",
    )
    canonical = listing.to_text()
    assert "rule from 100 until 50 if R conc > 1 and\nrule from 100 until 50 always change R conc 1" in canonical
    assert load_listing(canonical) == listing


# ---- prepattern ----------------------------------------------------------------------


def test_fig_5_2_cell_480_is_the_centre_of_the_31_by_31_grid():
    listing = load_listing("fig5.2")
    cells = listing.prepattern(jax.random.key(0))
    assert int(cells.count) == 961
    p = values(cells["P"])
    assert np.flatnonzero(p).tolist() == [480] and p[480] == 1.0
    np.testing.assert_allclose(values(cells.position[480]), [0.0, 0.0], atol=1e-6)
    np.testing.assert_allclose(values(cells.diffusion[:, 0]), [0.05, 0.0], rtol=1e-6)
    assert [float(r.when[0].right) for r in listing.rules] == [1.0, 0.0]


def test_fig_5_1_cells_75_to_149_are_rows_5_to_9():
    cells = load_listing("fig5.1").prepattern(jax.random.key(0))
    position = values(cells.position)
    permeable = np.flatnonzero(np.asarray(cells.diffusion[0]) == np.float32(0.1))
    assert permeable.tolist() == list(range(75, 150))
    rows = np.unique(np.round(position[permeable, 1], 6))
    np.testing.assert_allclose(rows, [-4.0, -2.0, 0.0, 2.0, 4.0])  # the middle five of 15 rows, 2 apart
    assert np.all(np.abs(position[np.delete(np.arange(225), permeable), 1]) > 5)
    r = values(cells["R"])
    assert np.flatnonzero(r).tolist() == [108] and r[108] == 75.0
    np.testing.assert_allclose(position[108], [-8.0, 0.0])  # row 7, column 3


def test_prepattern_noise_is_uniform_and_deterministic():
    text = "define chemical U\ndefine chemical V\nuse chemical U conc 4 dev 2 diff 0.04 dev 0.01\ncreate sqr_grid 12 10 dev 0.5\n"
    listing = load_listing(text)
    a, b = listing.prepattern(jax.random.key(3)), listing.prepattern(jax.random.key(3))
    for name in ("position", "concentration", "diffusion", "polarity"):
        np.testing.assert_array_equal(values(getattr(a, name)), values(getattr(b, name)))
    c = listing.prepattern(jax.random.key(4))
    assert not np.array_equal(values(a["U"]), values(c["U"]))
    u = values(a["U"])
    assert 2.0 <= u.min() < 2.5 and 5.5 < u.max() <= 6.0  # uniform on [4 - 2, 4 + 2]
    rates = values(a.diffusion[0])
    assert 0.03 - 1e-6 <= rates.min() and rates.max() <= 0.05 + 1e-6 and rates.std() > 0.003
    assert np.all(values(a["V"]) == 0.0) and np.all(values(a.diffusion[1]) == 0.0)  # never named: 0
    jitter = values(a.position) - hex_free_grid(10, 12)
    assert np.abs(jitter).max() <= 0.5 + 1e-6 and np.abs(jitter).max() > 0.3


def hex_free_grid(rows, cols):
    r, c = np.divmod(np.arange(rows * cols), cols)
    xy = np.stack([2.0 * c, 2.0 * r], axis=1)
    return xy - (xy.min(axis=0) + xy.max(axis=0)) / 2


def test_polarity_defaults_and_set_replaces():
    a16 = load_listing("A.16")
    cells = a16.prepattern(jax.random.key(1))
    assert cells.anisotropic == (False, True) and values(cells.upper)[0] == pytest.approx(6.3)
    polarised, angle = values(cells.polarised).astype(bool), values(cells.polarity)
    assert not polarised[:5000].any() and polarised[5000:].all()
    np.testing.assert_allclose(angle[5000:], math.pi / 2, rtol=1e-6)  # `use polarity 90`
    rates = values(cells.diffusion)
    np.testing.assert_allclose(rates[:, :5000].T, np.broadcast_to([0.011, 0.003], (5000, 2)), rtol=1e-6)  # replaced, not added
    np.testing.assert_allclose(rates[:, 5000:].T, np.broadcast_to([0.30, 0.02], (5000, 2)), rtol=1e-6)
    u = values(cells["U"])
    assert 2.0 <= u.min() and u.max() <= 6.0 and u[:5000].std() > 0.5
    assert a16.commands[-1] == SetCells(0, 4999, "V", (4.0, 2.0), (0.003, 0.0), "none")

    # no `use polarity` line: polarised along +x (Fig. 6.5 grows oriented patterns without one)
    default = load_listing("listing4.1").to_text().replace("100 100", "3 2")
    cells = load_listing(default).prepattern(jax.random.key(0))
    assert values(cells.polarised).all() and np.all(values(cells.polarity) == 0.0)
    text = ("define chemical R\nuse polarity none\ncreate cell 0 0\nuse polarity 45 dev 10\ncreate cell 4 0 fixed\n"
            "set cell 0 polarity -30\nset cell 1 polarity none\n")
    cells = load_listing(text).prepattern(jax.random.key(0))
    assert values(cells.polarised).tolist() == [1.0, 0.0] and values(cells.fixed).tolist() == [0.0, 1.0]
    assert values(cells.polarity)[0] == pytest.approx(math.radians(-30))


def test_create_kinds_follow_the_grids():
    text = ("define chemical R\n"
            "create hex_circle 5 at 100 0\n"
            "create sqr_circle 4.5\n"
            "create hex_grid 3 2 at 0 50\n"
            "create cell 7 -3\n")
    cells = load_listing(text).prepattern(jax.random.key(0))
    xy = values(cells.position)
    disc = xy[xy[:, 0] > 50] - [100, 0]
    i, j = np.meshgrid(np.arange(-9, 10), np.arange(-9, 10))
    lattice = np.stack([2.0 * i + j, math.sqrt(3) * j], -1).reshape(-1, 2)  # the hexagonal lattice through the centre
    inside = lattice[np.hypot(*lattice.T) <= 5]
    assert len(disc) == len(inside) == 19
    np.testing.assert_allclose(sorted(map(tuple, disc.round(4))), sorted(map(tuple, inside.round(4))), atol=1e-3)
    square = xy[19:-7]  # the cells are numbered in the order of the create lines
    expected = [(2 * i, 2 * j) for j in range(-3, 4) for i in range(-3, 4) if math.hypot(2 * i, 2 * j) <= 4.5]
    np.testing.assert_allclose(sorted(map(tuple, square)), sorted(expected), atol=1e-5)
    assert len(xy) == 19 + 21 + 6 + 1
    np.testing.assert_allclose(xy[-7:-1], hex_oracle(2, 3) + [0, 50], atol=1e-5)
    np.testing.assert_allclose(xy[-1], [7, -3])


def test_create_shape_reads_letters_relative_to_the_listing(tmp_path):
    (tmp_path / "shapes").mkdir()
    (tmp_path / "shapes" / "L.txt").write_text("X..\nX..\nXYZ\n")
    listing_file = tmp_path / "shape.txt"
    listing_file.write_text('define chemical R\ncreate shape "shapes/L.txt" at 10 0 fixed\nset cell 1 chemical R conc 5\n')
    listing = load_listing(listing_file)
    assert listing.commands[0] == Create("shape", (), "shapes/L.txt", at=(10.0, 0.0), fixed=True)
    cells = listing.prepattern(jax.random.key(0))
    # numbered from the lowest row (the file's last line) up, left to right
    np.testing.assert_allclose(values(cells.position), [[8, -2], [10, -2], [12, -2], [8, 0], [8, 2]])
    assert values(cells.fixed).all() and values(cells["R"]).tolist() == [0, 5, 0, 0, 0]
    assert load_listing(listing.to_text(), directory=tmp_path).prepattern(jax.random.key(0)).count == 5
    with pytest.raises(ValueError, match=r"<text>:2: cannot read the shape file"):
        load_listing(listing_file.read_text(), directory=tmp_path / "elsewhere").prepattern(jax.random.key(0))


def test_colormaps():
    white_black = load_listing("A.14").colormap
    assert isinstance(white_black, Gradient) and white_black.stops == ((0.0, (255, 255, 255)), (1.0, (0, 0, 0)))
    table = load_listing("A.1").colormap.table()
    assert tuple(table[0]) == (255, 255, 255) and tuple(table[-1]) == (0x42, 0x00, 0x09)
    rings = load_listing("A.2").colormap.table()  # slots 40 and 80: constant outside them
    assert (rings[:100] == (0x0E, 0xE1, 0xDA)).all() and (rings[210:] == (0x80, 0x76, 0x3E)).all()

    wireworld = load_listing("A.12")
    assert wireworld.colormap_select == "striped"
    table = wireworld.colormap.table()
    colours = [(0x30, 0x30, 0x30), (0x00, 0x80, 0xFF), (0xFF, 0xFF, 0xFF), (0xFF, 0x80, 0x00)]
    for j, rgb in enumerate(table):  # each slot's colour repeats up to the next slot
        stripe = sum(j / 255 >= s / 99 for s in (25, 50, 75))
        assert tuple(rgb) == colours[stripe], j
    for state in range(4):  # states 0..3 normalised to [0, 1] show their own colours
        assert tuple(table[round(state / 3 * 255)]) == colours[state]

    heat = load_listing("define chemical R\ncolormap select heat\n").colormap.table()
    assert tuple(heat[0]) == (0, 0, 255) and tuple(heat[-1]) == (255, 0, 0)
    rgb = load_listing('define chemical R\ncolormap slot 0 use rgb 1 2 3\ncolormap slot 99 use color "#ffffff"')
    assert rgb.colormap.stops == ((0.0, (1, 2, 3)), (1.0, (255, 255, 255)))
    assert load_listing(rgb.to_text()) == rgb and load_listing("listing4.1").colormap is None


def test_snap_repeat_and_steps():
    listing = load_listing("define chemical R\nsnap from 100 repeat 4 step 50 then exit\nsnap at 0 10\nstop at 500\n")
    assert listing.snaps[0].iterations == (100, 150, 200, 250) and listing.steps == 250
    assert listing.snaps[1] == Snap((0, 10)) and load_listing(listing.to_text()) == listing
    assert load_listing("fig5.1").steps is None


# ---- errors --------------------------------------------------------------------------

HEADER = "define chemical U\ndefine chemical V\ncreate sqr_grid 3 3\n"


@pytest.mark.parametrize("body, line, message", [
    ("grow cells", 4, "unknown command 'grow'"),
    ("rule if W conc > 1 change U conc 1", 4, "'W' is none of these"),
    ("rule always change W conc 1", 4, "unknown chemical 'W'"),
    ("\n// comment\ncreate sqr_grid 10", 6, "missing the number of rows after '10'"),
    ("use chemical U conc", 4, "missing the conc after 'conc'"),
    ("rule always change U conc 1\nrule if U conc > 2 and\n\n// nothing follows", 5, "the rule ends in 'and' but no rule follows"),
    ("rule if U conc > 2 and\nstop at 10", 5, "expected a rule to complete the 'and' on line 4"),
    ("rule always change U conc 1 and", 4, "unexpected 'and' after the action"),
    ("rule always react U V scale 0.01 turing alpha U conc beta 12", 4, "alpha must be a number"),
    ("rule probability 1.5 divide", 4, r"Chance.probability must lie in \[0, 1\]"),
    ("rule from 10 until x always divide", 4, "the last iteration after 'until' must be an integer, found 'x'"),
    ("rule always change U conc PAT", 4, "'PAT' is none of these"),
    ("rule if U > 1 divide", 4, "expected 'conc' or 'diff' after chemical U, found '>'"),
    ("create hex_grid 3 3 wrap", 4, "'wrap' .*applies to sqr_grid only, not to create hex_grid"),
    ("create sqr_grid 3 3 wrap wrap", 4, r"unexpected 'wrap' \(create sqr_grid takes at, dev, fixed, wrap, once each\)"),
    ("create sqr_grid 3 3 wrap 5", 4, "unexpected '5'"),
    ("define domain 10 10\ncreate sqr_grid 3 3 wrap", 5, "'wrap' makes the domain a torus, but line 4 already set"),
    ("create sqr_grid 3 3 wrap\ndefine domain 10 10", 5, r"line 4 already made the domain a torus \('wrap'\)"),
    ("create sqr_grid 3 3 wrap\ncreate sqr_grid 3 3 at 10 0 wrap", 5, "'wrap' makes the domain a torus, but line 4"),
    ("define chemical U", 4, r"U is already defined \(a chemical\)"),
    ("rule always map U conc 0 1 to M 0 1\ndefine chemical M", 5, r"M is already defined \(a map\)"),
    ("rule always map U conc 0 1 to V 0 1", 4, "a map's name must be a word other than a chemical"),
    ("stop at 10\nstop at 20", 5, "stop at was already given on line 4"),
    ('colormap slot 5 use color "notacolour"', 4, "unknown colour 'notacolour'"),
    ("colormap slot 100 use rgb 0 0 0", 4, r"slot number must lie in 0..99"),
    ("set cells 5 to 2 chemical U conc 1", 4, "the index range 5 to 2 is empty"),
    ("set cell 1 chemical U", 4, "set changes nothing"),
    ("define time_step 0", 4, "the time step must be > 0"),
    ("rule always divide direction 10 sideways", 4, "unexpected 'sideways' after the action"),
    ("use chemical U conc nan", 4, "the conc must be a number, found 'nan'"),
    ('create shape "broken.txt', 4, "unterminated quote"),
])
def test_malformed_lines_name_their_line(body, line, message):
    text = HEADER + body + "\n"
    with pytest.raises(ValueError, match=rf"^bad:{line}: .*{message}"):
        load_listing(text, name="bad")


def test_error_quotes_the_line_and_no_chemical():
    with pytest.raises(ValueError) as err:
        load_listing(HEADER + "rule if AGE = 3 divide   // comment\n", name="x")
    assert str(err.value) == ("x:4: expected a comparison (==, !=, <, <=, >, >= or in), found '=' "
                              "(got 'rule if AGE = 3 divide   // comment')")
    with pytest.raises(ValueError, match="defines no chemical"):
        load_listing("create cell 0 0\n")


def test_set_out_of_range_names_its_line():
    listing = load_listing(HEADER + "set cells 5 to 9 chemical U conc 1\n", name="bad")
    with pytest.raises(ValueError, match=r"^bad:4: cells 5 to 9 out of range: the cells created before this line "
                                         r"are cells 0 to 8 \(got 'set cells 5 to 9 chemical U conc 1'\)"):
        listing.prepattern(jax.random.key(0))
    early = load_listing("define chemical U\nset cell 0 chemical U conc 1\ncreate cell 0 0\n", name="early")
    with pytest.raises(ValueError, match="^early:2: cell 0 out of range: .* are no cells"):
        early.prepattern(jax.random.key(0))


def test_rule_key_sees_numbers_and_structure():
    a, b = load_listing("A.14").rules
    assert rule_key(a) == rule_key(load_listing("A.14").rules[0]) and rule_key(a) != rule_key(b)


# ---- running -------------------------------------------------------------------------


def test_run_fig_5_2_on_a_7_by_7_grid():
    small = load_listing("fig5.2").to_text().replace("31 31", "7 7").replace("set cell 480", "set cell 24")
    listing = load_listing(small)
    cells = listing.run(steps=20)
    assert int(cells.count) == 49 and int(cells.step) == 20 and bool(cells.ok)
    r, p = values(cells["R"])[:49], values(cells["P"])[:49]
    assert p[24] == 1.0 and np.count_nonzero(p) == 1  # P does not diffuse (diff 0)
    # diffusion conserves R: the producer added 0.8 per iteration, the others took at most 0.001 each
    assert 20 * 0.8 - 20 * 48 * 0.001 - 1e-3 <= r.sum() <= 20 * 0.8 + 1e-3
    assert r.argmax() == 24 and r[24] < 20 * 0.8
    grid = r.reshape(7, 7)  # the grid's symmetries: mirror images and transpose
    np.testing.assert_allclose(grid, grid[::-1], rtol=1e-4, atol=1e-6)
    np.testing.assert_allclose(grid, grid.T, rtol=1e-4, atol=1e-6)
    with pytest.raises(ValueError, match="has no 'stop at'"):
        load_listing(small.replace("stop at 4000\n", "")).run()


def test_run_grows_capacity_when_divisions_overflow():
    listing = load_listing("define chemical R\ncreate sqr_grid 5 2\nrule always divide direction 137.5\n")
    # 10 -> 160 cells in 4 iterations; the first capacity, 10 + 10 // 4 + 64 = 76, is
    # outgrown at iteration 2 and the piece runs again with 114, then 171
    grown = listing.run(steps=4)
    roomy = listing.run(steps=4, capacity=400)
    assert int(roomy.count) == int(grown.count) == 160 and grown.capacity == 171
    np.testing.assert_allclose(values(grown.position[:160]), values(roomy.position[:160]), atol=1e-5)
    np.testing.assert_array_equal(values(grown.birth[:160]), values(roomy.birth[:160]))
    with pytest.raises(SimulationError, match="did not fit in the capacity of 12 cells"):
        listing.run(steps=4, capacity=12)  # a capacity you pass is used as given
