"""Execute the notebooks at their small size and store the executed copies for the site.

    python docs/_scripts/execute_notebooks.py [NAME ...]     # run (all, or those matching NAME)
    python docs/_scripts/execute_notebooks.py --annotate     # only (re)write the site notes

Reads `notebooks/*.ipynb` (committed without outputs), runs each top to bottom in a fresh
kernel with `MORPHOJAX_NOTEBOOK_SIZE=small` (the size the test suite runs them at), and
writes the executed notebook, outputs included, to `docs/notebooks/`. A notebook that fails
is stored as it is in `notebooks/`, without outputs, and its note says so. Each copy gets a
first cell saying how it was run, and its "paper 00N" references become links to the
bibliography. The site renders these copies as stored; it never executes a notebook at build
time.
"""

from __future__ import annotations

import os
import re
import sys
import time
from pathlib import Path

import nbformat

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "docs" / "notebooks"
# notebook pages are served at notebooks/NAME/, so the bibliography is two levels up
BIBLIOGRAPHY = "../../bibliography/"
SOURCES = {"000": ("Malheiros 2017", "malheiros2017"), "001": ("Malheiros et al. 2020", "malheiros2020"),
           "002": ("Dur 2023", "dur2023"), "003": ("Tinson 2022", "tinson2022"),
           "004": ("Lundelius", "lundelius")}


def cite_sources(text: str) -> str:
    def link(match):
        short, anchor = SOURCES[match.group(1)]
        return f"[{short}]({BIBLIOGRAPHY}#{anchor})"
    return re.sub(r"\b[Pp]aper (00[0-4])\b", link, text)


NOTE_STARTS = ("*Rendered from a run", "*Shown without outputs*")


def annotate(nb) -> None:
    """Put the note on how the copy was run under the title, and link the sources."""
    info = nb.metadata.get("morphojax_executed", {})
    if info.get("seconds") is not None:
        note = (f"*Rendered from a run at the small size* (`MORPHOJAX_NOTEBOOK_SIZE=small`, the test "
                f"suite's size: smaller lattices and fewer steps than at full size; {info['seconds']} s on "
                f"a 2-core CPU, morphojax {info.get('version', '0.1.0')}). Run it yourself with "
                f"`jupyter lab notebooks/` for the full size.")
    else:
        note = ("*Shown without outputs*: this notebook was not executed for the site. Run it with "
                "`jupyter lab notebooks/`.")
    # drop a note an earlier pass wrote (as a cell of its own, or under the title)
    nb.cells = [c for c in nb.cells if not (c.cell_type == "markdown" and c.source.startswith(NOTE_STARTS))]
    for cell in nb.cells:
        if cell.cell_type == "markdown":
            cell.source = "\n".join(line for line in cell.source.split("\n") if not line.startswith(NOTE_STARTS))
            cell.source = re.sub(r"\n{3,}", "\n\n", cell.source)
    first = nb.cells[0] if nb.cells else None
    if first is not None and first.cell_type == "markdown" and first.source.startswith("# "):
        title, _, rest = first.source.partition("\n")
        first.source = f"{title}\n\n{note}\n\n{rest.lstrip()}".rstrip() + "\n"
    else:
        nb.cells.insert(0, nbformat.v4.new_markdown_cell(note))
    nb.metadata.pop("morphojax_site_note", None)
    for cell in nb.cells:
        if cell.cell_type == "markdown":
            cell.source = cite_sources(cell.source)


def execute(names: list[str]) -> int:
    from nbclient import NotebookClient

    import morphojax

    os.environ["MORPHOJAX_NOTEBOOK_SIZE"] = "small"
    sources = sorted((ROOT / "notebooks").glob("*.ipynb"))
    if names:
        sources = [p for p in sources if any(n in p.name for n in names)]
    OUT.mkdir(parents=True, exist_ok=True)
    failed = 0
    for src in sources:
        nb = nbformat.read(src, as_version=4)
        start = time.perf_counter()
        client = NotebookClient(nb, timeout=1800, kernel_name="python3",
                                resources={"metadata": {"path": str(src.parent)}})
        try:
            client.execute()
        except Exception as err:  # keep going: store the notebook as it is, and say which failed
            failed += 1
            print(f"{src.name}: FAILED after {time.perf_counter() - start:.0f} s: {str(err)[-1500:]}", flush=True)
            nb = nbformat.read(src, as_version=4)
        else:
            nb.metadata["morphojax_executed"] = {"size": "small", "seconds": round(time.perf_counter() - start),
                                                 "version": morphojax.__version__}
            print(f"{src.name}: {time.perf_counter() - start:.0f} s", flush=True)
        annotate(nb)
        nbformat.write(nb, OUT / src.name)
    return 1 if failed else 0


def annotate_stored() -> int:
    for path in sorted(OUT.glob("*.ipynb")):
        nb = nbformat.read(path, as_version=4)
        annotate(nb)
        nbformat.write(nb, path)
    return 0


if __name__ == "__main__":
    if sys.argv[1:] == ["--annotate"]:
        sys.exit(annotate_stored())
    sys.exit(execute(sys.argv[1:]))
