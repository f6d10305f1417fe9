"""Fixtures of the reproduction's tests."""

import json
from pathlib import Path

import pytest


@pytest.fixture
def fake_reproduce(monkeypatch) -> dict:
    """`pinnedballs.run.reproduction.reproduce` replaced by a stand-in that writes an empty report and records
    the keyword arguments the command line gave it (the returned dict)."""
    import pinnedballs.run.reproduction as reproduction

    seen: dict = {}

    def fake(out, **kwargs):
        seen.update(kwargs)
        out = Path(out)
        out.mkdir()
        (out / "results.json").write_text(json.dumps({"wall_seconds": 0.0, "failures": []}))
        return out / "report.md"

    monkeypatch.setattr(reproduction, "reproduce", fake)
    return seen
