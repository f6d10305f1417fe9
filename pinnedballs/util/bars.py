"""The bars `util.progress` shows: tqdm's text bar, or its widget inside a Jupyter kernel with ipywidgets.

Each bar tells its rate from a moment `Progress` sets (the call's start, or the end of its last
compile: the time a compile takes is no speed), and none while it has none (tqdm would say '?'). The widget is displayed
under an id, and closing it puts its final state in the output's text, which a saved notebook keeps
beside the widget (tqdm's own leaves the state it was first displayed in: "0/6", "0.00 steps"). Closed
with ``failed=`` (`Progress` says how the call ended), the widget is red only for an error or an
interruption: tqdm's own close takes any count below the total for one.
"""

from __future__ import annotations

import functools
import sys

__all__ = ["open_bar", "close_bar", "widgets_available"]


#: a bar's format while it has no rate (tqdm's own, less its rate): with a total, and without one
NO_RATE = ("{l_bar}{bar}| {n_fmt}/{total_fmt} [{elapsed}{postfix}]", "{desc}: {n_fmt}{unit} [{elapsed}{postfix}]")


class _Rate:
    """A tqdm bar whose rate counts from ``since``, ``(time, count)``; None: unknown, and not shown."""

    since = None

    @property
    def format_dict(self):
        d = super().format_dict
        d["rate"] = self._rate()
        if not d["rate"] and not d.get("bar_format"):  # nothing has run since: no rate, rather than '?'
            d["bar_format"] = NO_RATE[d.get("total") is None]
        return d

    def _rate(self) -> float:
        if self.since is None:
            return 0.0  # tqdm shows a rate of 0 as '?'
        t, n = self.since
        dt = self._time() - t
        return (self.n - n) / dt if dt > 0 else 0.0


class _Widget:
    """tqdm's widget, displayed under an id: `close` shows its final state in the output's text too."""

    def __init__(self, *args, **kwargs):
        from IPython.display import display

        super().__init__(*args, display=False, **kwargs)
        self._handle = display(self.container, display_id=True)

    def close(self, failed: bool | None = None) -> None:
        """Close on the final state, coloured by how the call ended: ``failed`` True (an error, an
        interruption) tqdm's danger red, False its normal end's colour whatever the count (a call may end
        normally below its total: a search exhausted before its bound), None tqdm's own guess (red below
        the total)."""
        shown = not self.disable  # (closing disables it)
        super().close()
        if failed is not None and shown:
            pbar = self.container.children[1]
            pbar.bar_style = "danger" if failed else ("success" if self.leave else pbar.bar_style)
        if self._handle is not None:
            self._handle.update(self.container)
            self._handle = None


@functools.cache
def _bar_class(widget: bool) -> type:
    if widget:
        from tqdm.notebook import tqdm as base

        return type("WidgetBar", (_Rate, _Widget, base), {})
    from tqdm.std import tqdm as base

    return type("TextBar", (_Rate, base), {})


@functools.cache
def widgets_available() -> bool:
    """Whether tqdm's notebook widget can be built (ipywidgets importable)."""
    try:
        from tqdm.notebook import IProgress
    except ImportError:
        return False
    return IProgress is not None


def open_bar(*, widget: bool, total: int | None, unit: str, desc: str, count: int, scale: bool, start: float,
             since: tuple[float, int] | None):
    """A bar shown now at ``count``, its elapsed time from ``start`` (``time.time()``), its rate from
    ``since`` (see `_Rate`); ``widget``: tqdm's notebook widget, else its text bar on stderr."""
    bar = _bar_class(widget)(total=total, initial=count, unit=f" {unit}", unit_scale=scale, desc=desc,
                             file=sys.stderr, dynamic_ncols=True, smoothing=0)
    bar.start_t, bar.since = start, since
    bar.refresh()
    return bar


def close_bar(bar, failed: bool) -> None:
    """Close a bar `open_bar` made on its final state; ``failed``: whether its call ended by an error or an
    interruption (a widget is red then, and only then: `_Widget.close`)."""
    if isinstance(bar, _Widget):
        bar.close(failed=failed)
    else:
        bar.close()
