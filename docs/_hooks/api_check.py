"""mkdocs hook: every public name has an entry in the generated API reference.

While the pages of `docs/api/` render, the anchors mkdocstrings writes (`id="package.name"`)
are collected; after the build, each name in the `__all__` of `morphojax`,
`morphojax.cells` and `fitting` must have one. A missing one is logged as a warning, so
`mkdocs build --strict` fails. (tests/test_docs.py checks the same from the Markdown and the
page generator, without building.)
"""

from __future__ import annotations

import importlib
import logging
import re

log = logging.getLogger("mkdocs.hooks.api_check")

PACKAGES = ("morphojax", "morphojax.cells", "fitting")
_anchors: set[str] = set()


def on_pre_build(config):
    _anchors.clear()


def on_page_content(html, page, config, files):
    if page.file.src_uri.startswith("api/"):
        _anchors.update(re.findall(r'id="([^"]+)"', html))
    return html


def on_post_build(config):
    for package in PACKAGES:
        module = importlib.import_module(package)
        missing = sorted(name for name in module.__all__ if f"{package}.{name}" not in _anchors)
        if missing:
            log.warning("the API reference lacks %d public name(s) of %s: %s", len(missing), package,
                        ", ".join(missing))
