"""mkdocs hook: the gallery's table of every preset, read from `morphojax.PRESETS` at build time.

The marker `<!-- all-presets -->` in a page is replaced by one row per registered preset
(name, kind, the figure it reproduces with a link to its source in the bibliography, and
its description), so a preset added to the registry appears without editing the page.
"""

from __future__ import annotations

import re

MARKER = "<!-- all-presets -->"

# how the registry names its sources -> the bibliography's entries
SOURCES = [
    (r"^leopard paper", "Malheiros et al. 2020", "malheiros2020"),
    (r"^thesis", "Malheiros 2017", "malheiros2017"),
    (r"^paper 002", "Dur 2023", "dur2023"),
    (r"^paper 003", "Tinson 2022", "tinson2022"),
    (r"^paper 004", "Lundelius", "lundelius"),
    (r"^Pearson 1993", "Pearson 1993", "pearson1993"),
]


def cite(figure: str, bibliography: str) -> str:
    for pattern, short, anchor in SOURCES:
        match = re.match(pattern, figure)
        if match:
            rest = figure[match.end():].strip()
            return f"[{short}]({bibliography}#{anchor}) {rest}".strip()
    figure = figure.replace("(Gardner 1970)", f"([Gardner 1970]({bibliography}#gardner1970))")
    return figure


def _cell(text: str) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def table(bibliography: str) -> str:
    import morphojax as mj

    rows = ["| preset | kind | reproduces | what it runs |", "|---|---|---|---|"]
    for name, preset in mj.PRESETS.items():
        rows.append(f"| `{name}` | {_cell(preset.kind)} | {cite(_cell(preset.figure), bibliography)} "
                    f"| {_cell(preset.description)} |")
    return "\n".join(rows)


def on_page_markdown(markdown, page, config, files):
    if MARKER not in markdown:
        return markdown
    depth = page.file.src_uri.count("/")
    return markdown.replace(MARKER, table("../" * depth + "bibliography.md"))
