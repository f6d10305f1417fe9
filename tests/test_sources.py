"""The package's sources say what the code does, not when or where it was measured (issue 47, item 3): dated
measurements live in ``benchmarks/results/measurements.md``, keyed by the module."""

import pathlib
import re

import pinnedballs

PACKAGE = pathlib.Path(pinnedballs.__file__).parent
MEASUREMENTS = PACKAGE.parent / "benchmarks" / "results" / "measurements.md"
#: a month, as 2026-11 or 2026-11-29; not an ISO timestamp's example (2026-12-01T23:30:53Z)
DATE = re.compile(r"\b20\d\d-[01]\d(?!-\d\dT)\b")


def test_no_source_quotes_a_date():
    sources = sorted(p for p in PACKAGE.rglob("*.py*") if p.suffix in {".py", ".pyi"})
    dated = [f"{p.relative_to(PACKAGE.parent)}:{n}" for p in sources
             for n, line in enumerate(p.read_text().splitlines(), 1) if DATE.search(line)]
    assert dated == []


def test_every_module_pointing_to_the_measurements_has_its_section():
    pointing = {".".join(p.relative_to(PACKAGE.parent).with_suffix("").parts) for p in PACKAGE.rglob("*.py")
                if "benchmarks/results/measurements.md" in p.read_text()}
    sections = set(re.findall(r"^## `([\w.]+)`", MEASUREMENTS.read_text(), re.M))
    assert pointing and pointing <= sections
