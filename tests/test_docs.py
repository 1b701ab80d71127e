"""The documentation without building it: every public name is in the API reference, the
README stays short and its links and commands hold.

The site itself is built strictly by `.ci/run` (`mkdocs build --strict`), where a hook also
checks the rendered API pages; these tests read the Markdown and `mkdocs.yml` only, so they
run fast and without the `docs` extra.
"""

from __future__ import annotations

import importlib
import importlib.util
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
PACKAGES = ("morphojax", "morphojax.cells", "fitting")


def _api_pages():
    """docs/api/*.md with the generated directives expanded, as the site's hook expands them."""
    spec = importlib.util.spec_from_file_location("api_pages", DOCS / "_hooks" / "api_pages.py")
    api_pages = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(api_pages)
    return {page.name: api_pages.expand(page.read_text(encoding="utf-8"))
            for page in sorted((DOCS / "api").glob("*.md"))}


def _directives() -> dict[str, list[str]]:
    """`::: identifier` directives of the API pages -> the option lines under each."""
    found: dict[str, list[str]] = {}
    for text in _api_pages().values():
        lines = text.splitlines()
        for i, line in enumerate(lines):
            match = re.match(r"^:::\s+([\w.]+)\s*$", line)
            if not match:
                continue
            options = []
            for following in lines[i + 1:]:
                if following.strip() and not following.startswith((" ", "\t")):
                    break
                options.append(following.strip())
            found[match.group(1)] = options
    return found


def test_the_site_shows_public_members_with_or_without_docstrings():
    config = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    # a package's members are chosen by its __all__ (griffe's "public"), and a member without
    # a docstring is still listed, so nothing exported is silently left out
    assert re.search(r"^\s+filters:\s*public\s*$", config, re.M)
    assert re.search(r"^\s+show_if_no_docstring:\s*true\s*$", config, re.M)
    assert "docs/_hooks/api_pages.py" in config
    for page in _api_pages():
        assert f"api/{page}" in config, f"api/{page} is not in the site's navigation"


def test_the_api_pages_leave_out_construction_machinery():
    """`__check_init__` and its kind stay off the API pages; `__init__` and operations stay;
    no private base is named."""
    griffe = pytest.importorskip("griffe")
    extension = "docs/_hooks/griffe_members.py:HideClassMachinery"
    options = re.search(r"^\s+extensions:\s*\n\s+- (\S+)", (ROOT / "mkdocs.yml").read_text(encoding="utf-8"), re.M)
    assert options and options.group(1) == extension, "mkdocstrings does not load the griffe extension"
    path, name = extension.split(":")

    def load(package):
        return griffe.load(package, search_paths=[str(ROOT)], allow_inspection=False,
                           extensions=griffe.load_extensions(f"{ROOT / path}:{name}"))

    turing = load("morphojax")["Turing"].members
    assert "__check_init__" not in turing and "__init__" in turing
    assert "__getitem__" in load("morphojax.cells")["Cells"].members
    # a private base is folded into the public class: its fields shown, its name not
    schnakenberg = load("morphojax")["Schnakenberg"].final_target
    assert {"a", "b", "du", "dv", "diffusion"} <= set(schnakenberg.members)
    assert [str(base) for base in schnakenberg.bases] == ["AbstractReaction"]


@pytest.mark.parametrize("package", PACKAGES)
def test_every_public_name_is_in_the_api_reference(package):
    module = importlib.import_module(package)
    directives = _directives()
    whole = directives.get(package)
    if whole is not None:  # the package rendered whole: its members come from __all__
        assert not any(option.startswith("members:") for option in whole), (
            f"`::: {package}` lists its members by hand; leave them to __all__ so new names appear")
        return
    missing = [name for name in module.__all__ if f"{package}.{name}" not in directives]
    assert not missing, f"public names of {package} missing from docs/api/: {missing}"


def test_a_new_public_name_lands_in_the_reference(monkeypatch):
    import morphojax

    monkeypatch.setattr(morphojax, "__all__", [*morphojax.__all__, "brand_new_name"])
    assert "::: morphojax.brand_new_name" in "".join(_api_pages().values())


def test_the_api_pages_document_the_packages_not_private_modules():
    for identifier in _directives():
        assert not any(part.startswith("_") for part in identifier.split(".")), identifier


README = ROOT / "README.md"


def test_the_readme_is_short_and_keeps_its_two_commands():
    text = README.read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 260
    assert "pip install -e . && morphojax run leopard" in text.splitlines()
    assert 'pip install -e ".[test]" && python -m pytest' in text.splitlines()
    # CI runs the README's test command verbatim
    assert 'pip install -e ".[test]" && python -m pytest' in (ROOT / ".ci" / "run").read_text(encoding="utf-8")


def test_the_readme_links_stay_inside_the_repository():
    text = README.read_text(encoding="utf-8")
    targets = re.findall(r"\]\(([^)\s]+)\)", text) + re.findall(r'src="([^"]+)"', text)
    for target in targets:
        if re.match(r"[a-z]+://", target) or target.startswith("#"):
            continue
        path = target.split("#")[0]
        assert not path.startswith(("/", "..")), f"README links outside the repository: {target}"
        assert (ROOT / path).exists(), f"README links to a missing file: {target}"


PAPER_NUMBER = re.compile(r"\b[Pp]apers? 00[0-4]\b")


def _public_docstrings():
    """(where, docstring) of every public name of the packages, its members and its module:
    the API pages and `--help` show these."""
    import inspect

    for package in PACKAGES:
        module = importlib.import_module(package)
        yield package, module.__doc__
        for name in module.__all__:
            obj = getattr(module, name)
            yield f"{package}.{name}", getattr(obj, "__doc__", None) if callable(obj) or inspect.isclass(obj) else None
            home = inspect.getmodule(obj)
            if home is not None:
                yield home.__name__, home.__doc__
            if inspect.isclass(obj):
                for member, value in vars(obj).items():
                    value = getattr(value, "__func__", value)
                    value = getattr(value, "fget", value)
                    yield f"{package}.{name}.{member}", getattr(value, "__doc__", None)


def test_pages_cite_the_bibliography_not_paper_numbers():
    for page in DOCS.rglob("*.md"):
        text = page.read_text(encoding="utf-8")
        assert not PAPER_NUMBER.search(text), f"{page.relative_to(ROOT)} says 'paper 00N'"
    # the API pages render the docstrings, and `morphojax presets` prints every preset's strings
    for where, doc in _public_docstrings():
        assert not (isinstance(doc, str) and PAPER_NUMBER.search(doc)), f"the docstring of {where} says 'paper 00N'"
    import morphojax as mj

    for name, preset in mj.PRESETS.items():
        for field in ("figure", "description"):
            text = str(getattr(preset, field))
            assert not PAPER_NUMBER.search(text), f"preset {name}'s {field} says 'paper 00N': {text}"
    anchors = set(re.findall(r"#([a-z]+\d{4}|lundelius)\b", (DOCS / "bibliography.md").read_text(encoding="utf-8")))
    anchors |= set(re.findall(r'id="([a-z]+\d*)"', (DOCS / "bibliography.md").read_text(encoding="utf-8")))
    for page in DOCS.rglob("*.md"):
        for anchor in re.findall(r"bibliography\.md#([\w-]+)", page.read_text(encoding="utf-8")):
            assert anchor in anchors, f"{page.relative_to(ROOT)} cites a missing entry #{anchor}"
