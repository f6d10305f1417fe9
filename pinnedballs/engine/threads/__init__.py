"""The paper's chain on every core with the bits of one: picks run by regions on the xoshiro stream
(`regions`) or by deterministic reservations on the counter stream (`reservations`); how threads wait, how
many there are, and when one thread is faster (`tuning`)."""


def __getattr__(name: str):
    """The names of ``pinnedballs.engine.threads`` when it was one module, now `tuning`'s (deprecated here)."""
    from . import tuning

    if name in tuning.__all__:
        import warnings

        warnings.warn(f"pinnedballs.engine.threads.{name} moved to pinnedballs.engine.threads.tuning",
                      DeprecationWarning, stacklevel=2)
        return getattr(tuning, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
