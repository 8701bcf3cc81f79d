"""``python -m host`` is the ``gaitlog`` command line."""

from host.cli import main

raise SystemExit(main())
