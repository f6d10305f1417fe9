"""Package-wide helpers, below everything else: errors that name what the user got wrong (`errors`), the one
helper that checks arguments (`checks`), files written whole or not at all (`atomic`), what the machine can
hold (`limits`), the progress a long call shows (`progress`, drawn by `bars`, saying so while numba
compiles: `compiling`), and Ctrl-C between chunks (`sigint`). Every room of the package may use them; they
use nothing of it."""
