"""One module per ``percept`` subcommand; see :mod:`percept.runtime.cli` for the contract."""
