"""``python -m pinnedballs`` and the ``pinnedballs`` program: the command line (`cli.main`).

A Ctrl-C at any moment is one line on stderr and exit status 130: set up here, first, before the command
line's imports (numpy, numba, h5py: the first second or so; `util.startup`), and while numba compiles
(`cli.interrupts.exit_while_compiling`). Importing the library sets up nothing: only its program does.
"""

import sys

from .util.startup import from_the_first_instant

from_the_first_instant()  # before anything heavy is imported

from .run.cli import interrupts  # noqa: E402 - after the Ctrl-C handler


def command_line() -> int:
    """The program (the ``pinnedballs`` script's too): a Ctrl-C while numba compiles ends it at once, then
    `cli.main.main`."""
    from .run.cli.main import main

    interrupts.exit_while_compiling()
    return main()


if __name__ == "__main__":
    sys.exit(command_line())
