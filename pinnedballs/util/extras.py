"""The optional dependencies, each installed by an extra of the package (``pyproject.toml``) and imported where
it is first needed: `need` gives the module, or says in one line which extra installs it.

==============  =========================================================================  ==========
extra           what needs it                                                              modules
==============  =========================================================================  ==========
``dask``        ensembles and studies on a Dask cluster (``--dask``, ``cluster=``)         dask, distributed
``gsd``         GSD trajectories (`pinnedballs.GSDWriter`, a spec's ``"trajectory"``,      gsd
                ``pinnedballs export``)
``pandas``      tables: ``to_pandas`` of a run, an ensemble or a study; a study's          pandas
                ``summary``, ``fit`` and figure
``xarray``      ``Results.to_xarray`` (its velocities read lazily, by dask)                xarray, dask
==============  =========================================================================  ==========

The core install (``python3 -m pip install .``) holds what a run, its spec, its results and its figures need;
``python3 -m pip install ".[test]"`` installs every extra the tests use.
"""

from __future__ import annotations

import importlib
from types import ModuleType

from .errors import InputError

__all__ = ["MissingExtra", "need", "missing", "PACKAGES"]

#: extra -> the packages it installs (the top-level modules whose absence it mends)
PACKAGES = {"dask": ("dask", "distributed"), "gsd": ("gsd",), "pandas": ("pandas",),
            "xarray": ("xarray", "dask", "pandas")}


class MissingExtra(InputError, ImportError):
    """An optional dependency that is not installed: the message names the extra that installs it (an
    `InputError`: the command line says it in one line and exits with status 2; an ``ImportError`` too)."""


def missing(what: str, package: str, extra: str) -> str:
    """The line that says ``what`` needs ``package``, and the extra that installs it."""
    return f'{what} needs {package}, which is not installed: python3 -m pip install ".[{extra}]" in the ' \
           f"pinnedballs checkout"


def need(module: str, what: str, extra: str) -> ModuleType:
    """The module ``module`` (e.g. ``"dask.distributed"``), imported; a `MissingExtra` saying that ``what``
    needs the package that is missing and naming ``extra`` (a key of `PACKAGES`) when one of its packages is
    not installed. A package that is installed but fails to import raises its own error."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        package = (exc.name or "").partition(".")[0]
        if package not in PACKAGES[extra]:
            raise
        raise MissingExtra(missing(what, package, extra)) from None
