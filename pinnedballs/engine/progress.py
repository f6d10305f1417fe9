"""Progress of a long call: a bar over a known total, or a count and its rate when the end is unknown.

Every long call takes ``progress``: ``True`` shows it (a widget in a Jupyter notebook with
ipywidgets, a line of text on stderr elsewhere, a log file included), ``False`` never, and ``None``
(the default) only where it helps: in a terminal or a notebook, and only once the call has run
`DELAY` seconds, so a short call prints nothing and a script's log stays clean. The display is
tqdm's (its notebook widget when ipywidgets is there, else its text bar).

`Progress` is updated with absolute counts (`Progress.update`) and cleared when its block ends.
"""

from __future__ import annotations

import sys

from .errors import FieldTypeError

__all__ = ["Progress", "shown", "DELAY"]

#: seconds a call runs before ``progress=None`` shows it
DELAY = 2.0


def _in_notebook() -> bool:
    """True inside a Jupyter kernel (notebook, lab, VS Code, Colab), as tqdm.autonotebook tells."""
    return "ipykernel.zmqshell" in sys.modules


def _on_a_terminal() -> bool:
    try:
        return sys.stderr is not None and sys.stderr.isatty()
    except (AttributeError, ValueError):  # a replaced or closed stderr
        return False


def shown(progress) -> tuple[bool, float]:
    """``(shown, delay in seconds)`` for a call's ``progress`` argument (True, False or None)."""
    if progress is None:
        return (_in_notebook() or _on_a_terminal()), DELAY
    if not isinstance(progress, bool):
        raise FieldTypeError("progress", f"must be True, False or None (shown where it helps), got {progress!r}")
    return progress, 0.0


def _bar_class():
    """tqdm's notebook widget inside a kernel when ipywidgets is importable, else its text bar."""
    if _in_notebook():
        try:
            from tqdm.notebook import IProgress, tqdm as widget
        except ImportError:
            IProgress = None
        if IProgress is not None:
            return widget
    from tqdm.std import tqdm

    return tqdm


class Progress:
    """A bar of ``done`` out of ``total`` ``unit``s (None: the count, its rate and the time, no end).

    progress: the call's argument (see the module's docstring); desc: a word or two before the bar;
    initial: the count already done; scale: counts in k, M, G (for millions of steps, not for a few
    replicas). A context manager: the bar is closed when the block ends.
    """

    def __init__(self, progress, total: int | None, unit: str, desc: str, initial: int = 0, *, scale: bool = True):
        visible, delay = shown(progress)
        self.bar = None
        if visible:
            self.bar = _bar_class()(total=total, initial=initial, unit=f" {unit}", unit_scale=scale, desc=desc,
                                    delay=delay, file=sys.stderr, dynamic_ncols=True, smoothing=0.1)

    @property
    def visible(self) -> bool:
        """Whether the bar is shown (or will be, after its delay)."""
        return self.bar is not None

    def update(self, done: int, postfix: str = "") -> None:
        """The count is now ``done``; ``postfix`` (e.g. ``"collisions=1,234"``) follows the bar."""
        if self.bar is None:
            return
        if postfix:
            self.bar.set_postfix_str(postfix, refresh=False)
        self.bar.update(done - self.bar.n)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None

    def __enter__(self) -> "Progress":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
