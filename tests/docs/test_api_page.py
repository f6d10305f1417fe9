"""The API page documents every name the guides teach: each `pb.NAME` a guide mentions and each
name a guide's code imports from a pinnedballs module has its own entry (``::: module.NAME``)."""

from __future__ import annotations

import importlib
import re
from pathlib import Path

import pytest

import pinnedballs as pb

DOCS = Path(__file__).resolve().parents[2] / "docs"
GUIDES = ("extending.md", "getting-started.md", "collisions.md", "trajectories.md", "orders.md", "testing.md")


def taught(page: str) -> set[str]:
    """Fully qualified names a guide uses: ``pb.X`` (as ``pinnedballs.X``) and ``from pinnedballs.m import a, b``."""
    text = (DOCS / page).read_text(encoding="utf-8")
    names = {f"pinnedballs.{m}" for m in re.findall(r"\bpb\.([A-Z_a-z][A-Za-z_]*)\b", text)}
    for module, imported in re.findall(r"from (pinnedballs(?:\.[a-z_]+)*) import ([A-Za-z_, ]+)", text):
        names |= {f"{module}.{n.strip()}" for n in imported.split(",") if n.strip()}
    return names


def documented() -> set[str]:
    return set(re.findall(r"^::: (\S+)", (DOCS / "api.md").read_text(encoding="utf-8"), flags=re.M))


def canonical(name: str) -> str:
    """``pinnedballs.X`` for a name the package exports, however the guide reached it."""
    module, _, attr = name.rpartition(".")
    obj = getattr(importlib.import_module(module), attr)
    return next((f"pinnedballs.{n}" for n in pb.__all__ if getattr(pb, n, None) is obj), name)


@pytest.mark.parametrize("page", GUIDES)
def test_every_name_a_guide_teaches_is_on_the_api_page(page):
    api = documented()
    missing = sorted(n for n in taught(page) - {"pinnedballs.__version__"}
                     if n not in api and canonical(n) not in api)
    assert not missing, f"{page} teaches names the API page does not document: {missing}"


@pytest.mark.parametrize("tutorial", sorted(p.name for p in (DOCS / "tutorials").glob("*.py")))
def test_a_tutorial_imports_only_names_the_api_page_documents(tutorial):
    """A tutorial teaches the public API: no internal helper (it imported `pinnedballs.plot.base.new_figure`)."""
    api = documented()
    internal = sorted(n for n in taught(f"tutorials/{tutorial}") if n not in api and canonical(n) not in api)
    assert not internal, f"{tutorial} imports names the API page does not document: {internal}"


def test_every_public_name_is_on_the_api_page():
    api = documented()
    assert not [n for n in pb.__all__ if n != "__version__" and f"pinnedballs.{n}" not in api]
