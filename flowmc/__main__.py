"""``python3 -m flowmc`` is the ``flowmc`` command."""

from flowmc.cli import main

raise SystemExit(main())
