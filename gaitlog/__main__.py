"""``python -m gaitlog`` is the ``gaitlog`` command line."""

from gaitlog.host.cli import main

raise SystemExit(main())
