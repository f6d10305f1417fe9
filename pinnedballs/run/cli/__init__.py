"""The command line: `main` (arguments, exit statuses, one-line errors), `commands` (the
subcommands) and `status` (the status line a terminal shows from the first second)."""
