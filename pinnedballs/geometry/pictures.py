"""How a geometry and a simulation show themselves (``plot()``, a notebook's table and picture).

`pinnedballs.plot` draws them from above: its `display` module installs itself here as it is
imported (``import pinnedballs`` imports it), so these rooms reach their pictures without importing
the plots, which stand on what they draw (analysis, geometry)."""

from __future__ import annotations

__all__ = ["install", "display"]

_installed = None


def install(shown) -> None:
    """Draw geometries and simulations with ``shown``, a module as `pinnedballs.plot.display`:
    ``state_picture``, ``geometry_html``, ``geometry_png``, ``simulation_html``, ``simulation_png``,
    ``mimebundle``."""
    global _installed
    _installed = shown


def display():
    """The display installed by `install`."""
    if _installed is None:
        raise ImportError("no pictures: pinnedballs.plot.display draws them (import pinnedballs imports it)")
    return _installed
