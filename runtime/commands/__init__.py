"""One module per ``percept`` subcommand; see :mod:`runtime.cli` for the contract."""
