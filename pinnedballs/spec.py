"""Run specs (a facade kept for old imports): the specs live in `pinnedballs.specs`, one module per idea."""

from .specs import *  # noqa: F401,F403
from .specs import __all__  # noqa: F401
from .specs.base import Count, FilePath, Positive, _in_file, _load_npy, _Spec, engine_errors  # noqa: F401
from .specs.initial import INIT_STREAM_KEY  # noqa: F401
from .specs.pydantic_errors import first_error  # noqa: F401
