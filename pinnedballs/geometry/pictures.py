"""How a geometry and a simulation show themselves (``plot()``, a notebook's table and picture).

`pinnedballs.plot.display` draws them from above, and these rooms stand below the plots (which stand on
what they draw: analysis, geometry). So they do not import it: `display` loads it by name when a picture
is first asked for, and it installs itself here (`install`); a test may install another.
"""

from __future__ import annotations

import importlib

__all__ = ["install", "display"]

#: the module that draws, as `pinnedballs.plot.display`, loaded by `display` when first asked
DRAWN_BY = __name__.rpartition(".geometry.")[0] + ".plot.display"

_installed = None


def install(shown) -> None:
    """Draw geometries and simulations with ``shown``, a module as `pinnedballs.plot.display`:
    ``state_picture``, ``geometry_html``, ``geometry_png``, ``simulation_html``, ``simulation_png``,
    ``mimebundle``."""
    global _installed
    _installed = shown


def display():
    """The display installed by `install`; `pinnedballs.plot.display`, loaded now, when none is yet."""
    if _installed is None:
        install(importlib.import_module(DRAWN_BY))  # as it installs itself when first imported
    return _installed
