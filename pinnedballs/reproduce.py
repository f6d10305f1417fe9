"""The paper's reproduction (a facade kept for old imports): it lives in `pinnedballs.reproduction`,
one module per idea; the command ``pinnedballs reproduce`` lives in `pinnedballs.cli`."""

from .reproduction import *  # noqa: F401,F403
from .reproduction import __all__  # noqa: F401
from .reproduction.plan import _label, paper_lattice_spec  # noqa: F401
