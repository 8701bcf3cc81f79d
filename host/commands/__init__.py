"""One module per ``gaitlog`` subcommand; see :mod:`host.cli` for the contract each module follows."""
