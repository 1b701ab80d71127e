"""mkdocs hook: the gallery's table of every preset, read from `morphojax.PRESETS` at build time.

The marker `<!-- all-presets -->` in a page is replaced by one row per registered preset
(name, kind, the figure it reproduces and its description, each source linked to the
bibliography), so a preset added to the registry appears without editing the page.
"""

from __future__ import annotations

import re

MARKER = "<!-- all-presets -->"

# how the registry names its sources -> the bibliography's entries
SOURCES = [
    (r"^leopard paper", "Malheiros et al. 2020", "malheiros2020"),
    (r"^thesis", "Malheiros 2017", "malheiros2017"),
    (r"^Dur 2023", "Dur 2023", "dur2023"),
    (r"^Tinson 2022", "Tinson 2022", "tinson2022"),
    (r"^Lundelius", "Lundelius", "lundelius"),
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


# a description names its source by author and year ("Tinson 2022", "Tinson's (2022) code")
CITED = re.compile(r"\b(Dur 2023|Dur's \(2023\)|Tinson 2022|Tinson's \(2022\)|Lundelius(?:'s)?)(?![\w-])")
ANCHORS = {"Dur": "dur2023", "Tinson": "tinson2022", "Lundelius": "lundelius"}


def cite_description(description: str, bibliography: str) -> str:
    def link(match):
        text = match.group(1)
        return f"[{text}]({bibliography}#{ANCHORS[re.match(r'[A-Za-z]+', text).group(0)]})"
    return CITED.sub(link, description)


def _cell(text: str) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def table(bibliography: str) -> str:
    import morphojax as mj

    rows = ["| preset | kind | reproduces | what it runs |", "|---|---|---|---|"]
    for name, preset in mj.PRESETS.items():
        rows.append(f"| `{name}` | {_cell(preset.kind)} | {cite(_cell(preset.figure), bibliography)} "
                    f"| {cite_description(_cell(preset.description), bibliography)} |")
    return "\n".join(rows)


def on_page_markdown(markdown, page, config, files):
    if MARKER not in markdown:
        return markdown
    depth = page.file.src_uri.count("/")
    return markdown.replace(MARKER, table("../" * depth + "bibliography.md"))
