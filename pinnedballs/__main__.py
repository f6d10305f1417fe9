"""``python -m pinnedballs``: the command line (`cli.main`). A Ctrl-C at any moment is one line on stderr
and exit status 130: while the package is imported (its ``__init__`` sees the command line starting,
`util.startup`), and while numba compiles (`cli.interrupts.exit_while_compiling`)."""

import sys

from .cli import interrupts


def command_line() -> int:
    """The program (the ``pinnedballs`` script's too): a Ctrl-C while numba compiles ends it at once, then
    `cli.main.main`."""
    from .cli.main import main

    interrupts.exit_while_compiling()
    return main()


if __name__ == "__main__":
    sys.exit(command_line())
