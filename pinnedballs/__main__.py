"""``python -m pinnedballs``: the command line (`cli.main`). A Ctrl-C at any moment is one line on stderr
and exit status 130 (`cli.interrupts`): from the first instant, while the package is imported, and while
numba compiles."""

import sys

from .cli import interrupts


def command_line() -> int:
    """The program: its Ctrl-C handled from here on, then `cli.main.main` (what the ``pinnedballs`` script
    may call too)."""
    interrupts.from_the_first_instant()  # before the heavy imports
    from .cli.main import main

    interrupts.exit_while_compiling()
    return main()


if __name__ == "__main__":
    sys.exit(command_line())
