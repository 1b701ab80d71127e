"""mkdocs hook: serve the committed benchmark results (images and tables) inside the site.

mkdocs only serves files under `docs/`; the gallery's images and the benchmark tables live
in `benchmarks/results/`, where the scripts write them. This hook adds those files to the
build under the same relative path (`benchmarks/results/...`), so pages link to them as
`benchmarks/results/gallery/leopard.png` (from the site's root) and `mkdocs build --strict`
checks every such link. Nothing is copied into `docs/`.
"""

from __future__ import annotations

import re
from pathlib import Path

from mkdocs.structure.files import File, InclusionLevel

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "benchmarks" / "results"
SERVED = {".png", ".md", ".json", ".csv", ".svg", ".gif"}


def on_files(files, config):
    for path in sorted(RESULTS.rglob("*")):
        if not path.is_file() or path.suffix not in SERVED:
            continue
        src_uri = path.relative_to(ROOT).as_posix()
        if files.get_file_from_path(src_uri) is not None:
            continue
        files.append(File(src_uri, str(ROOT), config["site_dir"], config["use_directory_urls"],
                          inclusion=InclusionLevel.NOT_IN_NAV if path.suffix == ".md" else InclusionLevel.UNDEFINED))
    return files


# the result tables name their sources by number; on the site they cite the bibliography
SOURCES = {"000": ("Malheiros 2017", "malheiros2017"), "001": ("Malheiros et al. 2020", "malheiros2020"),
           "002": ("Dur 2023", "dur2023"), "003": ("Tinson 2022", "tinson2022"),
           "004": ("Lundelius", "lundelius")}


def cite_sources(text: str, bibliography: str) -> str:
    """`paper 002` -> `[Dur 2023](bibliography.md#dur2023)`, and so on for the five sources."""
    def link(match):
        short, anchor = SOURCES[match.group(1)]
        return f"[{short}]({bibliography}#{anchor})"
    return re.sub(r"\b[Pp]aper (00[0-4])\b", link, text)


def unserved_links_as_text(markdown: str, src_uri: str) -> str:
    """A result table's link to a file the site does not serve (a script, a log) becomes text.

    The scripts write their tables for the repository, where `../bench_core.py` resolves; on the
    site only the files this hook serves exist, so such a link is shown as `text (path)`
    instead of failing the strict build.
    """
    here = (ROOT / src_uri).parent

    def keep_or_flatten(match):
        bang, text, target = match.group(1), match.group(2), match.group(3)
        if re.match(r"[a-z]+:", target) or target.startswith("#"):
            return match.group(0)
        path = (here / target.split("#")[0]).resolve()
        served = path.is_file() and path.suffix in SERVED and RESULTS in path.parents
        if served:
            return match.group(0)
        return f"{text} (`{target}`)" if not bang else f"`{target}`"

    return re.sub(r"(!?)\[([^\]]*)\]\(([^)\s]+)\)", keep_or_flatten, markdown)


def on_page_markdown(markdown, page, config, files):
    if not page.file.src_uri.startswith("benchmarks/results/"):
        return markdown
    depth = page.file.src_uri.count("/")
    markdown = unserved_links_as_text(markdown, page.file.src_uri)
    return cite_sources(markdown, "../" * depth + "bibliography.md")
