"""hypothesis' entry point for pinnedballs (``[project.entry-points.hypothesis]`` in pyproject.toml).

hypothesis calls `setup` as it is imported, in an environment where pinnedballs is installed: it imports
`pinnedballs.testing.strategies`, which registers its strategies for ``st.from_type(pb.Geometry)`` and
the others. The one way they are registered, whichever of the two a program imports first; it costs
that import (the geometries, rules, schedulers and specs: about a second), as hypothesis' entry points
do. This module stands outside the package, as hypothesis' own ``_hypothesis_pytestplugin`` does.
"""


def setup() -> None:
    """Called by hypothesis as it is imported: registers pinnedballs' strategies."""
    import pinnedballs.testing.strategies  # noqa: F401 - registers them
