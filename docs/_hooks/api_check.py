"""mkdocs hook: every public name has an entry in the generated API reference.

After a page of `docs/api/` is rendered, each name in the `__all__` of the package it
documents must have an anchor (`id="package.name"`, as mkdocstrings writes them). A missing
one is logged as a warning, so `mkdocs build --strict` fails. (tests/test_docs.py checks the
same from the Markdown, without building.)
"""

from __future__ import annotations

import importlib
import logging
import re

log = logging.getLogger("mkdocs.hooks.api_check")

PAGES = {"api/morphojax.md": "morphojax", "api/cells.md": "morphojax.cells", "api/fitting.md": "fitting"}
# names documented on a page of their own rather than as a member
ELSEWHERE = {("morphojax", "cells"): "api/cells.md"}


def on_page_content(html, page, config, files):
    package = PAGES.get(page.file.src_uri)
    if package is None:
        return html
    module = importlib.import_module(package)
    anchors = set(re.findall(r'id="([^"]+)"', html))
    missing = [name for name in module.__all__
               if f"{package}.{name}" not in anchors and (package, name) not in ELSEWHERE]
    if missing:
        log.warning("API reference %s lacks %d public name(s) of %s: %s",
                    page.file.src_uri, len(missing), package, ", ".join(sorted(missing)))
    return html
