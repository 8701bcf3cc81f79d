"""One module per ``gaitlog`` subcommand; see :mod:`gaitlog.host.cli` for the contract each module follows."""
