"""docs/public-api.md says what 1.0 promises (issue 47, item 3): every name it lists exists, every public name
(``pinnedballs.__all__``, ``pinnedballs.testing``, its strategies, the engine's door) and every name the API
reference documents is on it, and its commands, exit statuses and spec keys are the package's own."""

from __future__ import annotations

import argparse
import importlib
import inspect
import re
from pathlib import Path

import pinnedballs as pb
import pinnedballs.engine as engine
import pinnedballs.testing as testing
import pinnedballs.testing.strategies as strategies
from pinnedballs.run.cli.commands import EXIT_ERROR, EXIT_INPUT, EXIT_INTERRUPTED, EXIT_OK
from pinnedballs.run.cli.main import _parser
from pinnedballs.specs.run import RunSpec
from pinnedballs.specs.study import StudySpec

DOCS = Path(__file__).resolve().parents[2] / "docs"
PAGE = (DOCS / "public-api.md").read_text(encoding="utf-8")
#: a module path with a name, or a bare name (of the module the section's heading names)
QUALIFIED, BARE = re.compile(r"pinnedballs(\.\w+)+"), re.compile(r"[A-Za-z_]\w*")


def sections() -> dict[str, str]:
    """The page's sections, heading -> text."""
    parts = re.split(r"^## (.+)$", PAGE, flags=re.M)
    return dict(zip(parts[1::2], parts[2::2]))


def promised() -> dict[str, str]:
    """The sections before "Not public" (what the page promises)."""
    out = {}
    for heading, text in sections().items():
        if heading == "Not public":
            break
        out[heading] = text
    return out


def listed() -> set[str]:
    """The fully qualified names the promised sections list: ``pinnedballs.m.NAME`` and ``pb.NAME`` as written,
    and a bare ``NAME`` in a list of a section whose heading names its module (`pinnedballs.testing`)."""
    names = set()
    for heading, text in promised().items():
        home = next((s for s in re.findall(r"`([^`]+)`", heading) if QUALIFIED.fullmatch(s) or s == "pinnedballs"),
                    None)
        for span in re.findall(r"`([^`]+)`", text):
            if QUALIFIED.fullmatch(span):
                names.add(span)
            elif span.startswith("pb.") and BARE.fullmatch(span[3:]):
                names.add(f"pinnedballs.{span[3:]}")
            elif home is not None and BARE.fullmatch(span) and span not in ("pb", "__all__"):
                names.add(f"{home}.{span}")
    return names


def resolve(name: str):
    """The object ``name`` (``pinnedballs.a.b.NAME``) names: the longest importable module, then attributes."""
    parts = name.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        for attr in parts[cut:]:
            obj = getattr(obj, attr)
        return obj
    raise ImportError(name)


def api_reference() -> set[str]:
    """The names docs/api.md documents: each ``::: NAME`` but a module's, whose story it shows, and the members
    a module's entry lists (``members: [A, b]``)."""
    out = set()
    for name, options in re.findall(r"^::: (\S+)\n((?:    .*\n)*)", (DOCS / "api.md").read_text(encoding="utf-8"),
                                    flags=re.M):
        if not inspect.ismodule(resolve(name)):
            out.add(name)
            continue
        members = re.search(r"members: \[([^\]]*)\]", options)
        out |= {f"{name}.{m.strip()}" for m in members.group(1).split(",")} if members else set()
    return out


def test_every_name_the_page_lists_exists():
    names = listed()
    assert len(names) > 150
    missing = []
    for name in sorted(names):
        try:
            resolve(name)
        except (ImportError, AttributeError):
            missing.append(name)
    assert missing == []


def test_every_public_name_is_on_the_page():
    public = {f"pinnedballs.{n}" for n in pb.__all__} | {f"pinnedballs.testing.{n}" for n in testing.__all__} \
        | {f"pinnedballs.testing.strategies.{n}" for n in strategies.__all__} \
        | {f"pinnedballs.engine.{n}" for n in engine.__all__}
    assert len(public) > 120 and sorted(public - listed()) == []


def test_every_name_the_api_reference_documents_is_on_the_page():
    documented = api_reference()
    assert "pinnedballs.rules.closing_speed" in documented and "pinnedballs.plot.field.speed_field" in documented
    assert sorted(documented - listed()) == []


def test_the_commands_and_exit_statuses_are_the_command_lines():
    text = sections()["The command line"]
    commands = {c for line in text.splitlines() if line.startswith(("- ", "  "))
                for c in re.findall(r"`pinnedballs (\w+)`", line)}
    subparsers, = (a for a in _parser()._actions if isinstance(a, argparse._SubParsersAction))
    assert commands == set(subparsers.choices)
    statuses = dict(re.findall(r"^\| (\d+) \| (\w+)", text, flags=re.M))
    assert statuses == {str(EXIT_OK): "done", str(EXIT_ERROR): "anything", str(EXIT_INPUT): "bad",
                        str(EXIT_INTERRUPTED): "interrupted"}


def test_the_spec_keys_are_the_specs():
    text = sections()["Files"]
    run, study = (re.findall(r'`"(\w+)"`', part) for part in text.split("**Study specs**"))
    assert [k for k in run if k != "kind"] == list(RunSpec.model_fields)  # (a component's "kind")
    assert study == list(StudySpec.model_fields)
