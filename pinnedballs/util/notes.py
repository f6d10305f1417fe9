"""`Note`: a warning the command line says once, as one line (``pinnedballs: note: ...``), where Python would show
a file and a line. A library module's warning that is one subclasses it (`pinnedballs.engine.margin.MarginWarning`).

Only the standard library is imported here: the command line watches for notes before it knows whether its
command loads the engine (``pinnedballs schema`` never does).
"""

from __future__ import annotations

__all__ = ["Note"]


class Note(UserWarning):
    """A warning the command line says once, in one line (`pinnedballs.run.cli.main`): what a run's result depends
    on, and what to do about it."""
