"""Schedulers: which contacts are tried, in which order.

One module per idea: `base` (`Scheduler`, what every scheduler gives the engine), `simple`
(the paper's uniform random pair and the sweeps), `rejection_free` (the paper's chain without
its rejected picks), `colored_sweep` (colour classes in parallel) and `replay` (a given order).
"""

from .base import Scheduler
from .colored_sweep import ColoredSweep
from .rejection_free import RejectionFree
from .replay import Replay
from .simple import RandomSweep, Sweep, UniformRandomPair

__all__ = ["Scheduler", "UniformRandomPair", "Sweep", "RandomSweep", "RejectionFree", "ColoredSweep", "Replay"]
