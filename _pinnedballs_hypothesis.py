"""hypothesis' entry point for pinnedballs (``[project.entry-points.hypothesis]`` in pyproject.toml).

`pinnedballs.testing.strategies` registers its strategies for ``st.from_type(pb.Geometry)`` and the
others as it is imported. This module stands outside the package, as hypothesis' own
``_hypothesis_pytestplugin`` does, so that importing hypothesis never imports pinnedballs (seconds:
numba, scipy): it imports the strategies only when pinnedballs is already imported; when hypothesis
comes first, pinnedballs imports them itself (the end of ``pinnedballs/__init__.py``).
"""

import sys


def setup() -> None:
    """Called by hypothesis as it is imported."""
    if "pinnedballs" in sys.modules and "pinnedballs.testing.strategies" not in sys.modules:
        import pinnedballs.testing.strategies  # noqa: F401 - registers them
