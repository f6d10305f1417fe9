"""Module paths that moved (`pinnedballs.util.moved`): code written against them keeps working, told once
where the module is now; the old names of renamed classes too."""

import importlib
import subprocess
import sys
import warnings

import pytest
from helpers import ROOT

import pinnedballs  # noqa: F401 - installs the finder
from pinnedballs.util.moved import MOVED, new_name

_FRESH = r"""
import warnings
warnings.simplefilter("always")
with warnings.catch_warnings(record=True) as seen:
    from pinnedballs.engine.loops import Selector, no_begin, no_change
    from pinnedballs.engine.random import bounded
    from pinnedballs.engine.limits import check_memory, run_bytes
    import pinnedballs.reproduction.extended.scaling_study as old
import pinnedballs.engine.sequential.loops as loops, pinnedballs.run.reproduction.extended.scaling_study as new
assert Selector is loops.Selector and old is new
for w in seen:
    print(w.category.__name__, w.filename, w.message)
"""


def test_every_old_path_names_a_module_that_is():
    for old, new in MOVED.items():
        assert importlib.util.find_spec(new) is not None, new
        assert new_name(old + ".x") == new + ".x" and new_name(old.replace("pinnedballs", "numpy")) is None


@pytest.mark.slow
def test_old_paths_import_the_modules_themselves_with_one_warning_each():
    """In a fresh process (the docs' imports of before): the same objects, and one DeprecationWarning a moved
    module, about the caller's line, naming where it is now; the submodules of a moved package are the
    moved ones, not second copies under the old names."""
    out = subprocess.run([sys.executable, "-c", _FRESH], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert len(lines) == 6, lines
    assert all(line.startswith("DeprecationWarning <string> pinnedballs.") for line in lines), lines
    assert "pinnedballs.engine.loops moved to pinnedballs.engine.sequential.loops; import it from there" in lines[0]
    assert "pinnedballs.reproduction.extended.scaling_study moved to pinnedballs.run.reproduction.extended." \
           "scaling_study" in lines[-1]


def test_renamed_classes_answer_to_their_old_names():
    from pinnedballs.engine.field import numbers, rational

    with pytest.warns(DeprecationWarning, match="ExactChain is pinnedballs.engine.field.rational.RationalChain"):
        assert rational.ExactChain is rational.RationalChain
    with pytest.warns(DeprecationWarning, match="Exact is pinnedballs.engine.field.numbers.FieldNumber"):
        assert numbers.Exact is numbers.FieldNumber
    with pytest.raises(AttributeError):
        rational.NoSuchChain  # noqa: B018
    from pinnedballs.engine import threads
    from pinnedballs.engine.threads import tuning

    with pytest.warns(DeprecationWarning, match="threads.most_threads moved to pinnedballs.engine.threads.tuning"):
        assert threads.most_threads is tuning.most_threads


def test_the_package_itself_uses_no_old_path():
    """Importing everything the package has warns of nothing: its own imports are the new paths."""
    import pkgutil

    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        for info in pkgutil.walk_packages(pinnedballs.__path__, "pinnedballs."):
            if ".gpu." in info.name or info.name.endswith("__main__"):
                continue  # numba-cuda's own imports are not ours; __main__ runs the command line
            importlib.import_module(info.name)
