"""``python -m tlac ...``: the same as the ``tlac`` command."""

from tlac.cli import main

raise SystemExit(main())
