"""`geometry.pictures`: a geometry and a simulation show themselves through the display `pinnedballs.plot`
installs, without importing the plots above them."""

from __future__ import annotations

import types

import numpy as np

import pinnedballs as pb
from pinnedballs.geometry import pictures
from pinnedballs.plot import display


def test_import_pinnedballs_installs_the_plots_display():
    assert pictures.display() is display


def test_the_pictures_come_from_the_display_installed(monkeypatch):
    g = pb.FlatTorus(4, 4)
    sim = pb.Simulation(g, np.ones((g.n_balls, 2)), seed=0)
    drawn = []
    shown = types.SimpleNamespace(
        state_picture=lambda geometry: lambda v, title=None, ax=None: drawn.append((geometry, v.sum(), title)),
        simulation_figure=lambda sim, what, ax=None, title=None: drawn.append((sim.geometry, what, title)),
        geometry_png=lambda obj: b"geometry", simulation_png=lambda obj: b"simulation",
        geometry_html=lambda obj, png: f"<{png.decode()}>", simulation_html=lambda obj, png: f"<{png.decode()}>",
        mimebundle=display.mimebundle)
    monkeypatch.setattr(pictures, "_installed", shown)
    g.plot(title="rest")
    sim.plot()
    assert drawn == [(g, 0.0, "rest"), (g, "state", None)]   # the simulation's kinds of figure: its state first
    assert (g._repr_png_(), g._repr_html_(), sim._repr_png_(), sim._repr_html_()) == \
        (b"geometry", "<geometry>", b"simulation", "<simulation>")
    assert sim._repr_mimebundle_() == {"text/html": "<simulation>", "image/png": b"simulation"}


def test_with_no_display_installed_the_first_picture_loads_the_plots(monkeypatch):
    """The rooms below the plots never import them: the first picture asked for loads them by name."""
    import matplotlib.figure

    from pinnedballs.plot import display

    monkeypatch.setattr(pictures, "_installed", None)
    assert isinstance(pb.FlatTorus(4, 4).plot(), matplotlib.figure.Figure)
    assert pictures.display() is display and pictures.DRAWN_BY == "pinnedballs.plot.display"
