"""``python -m tlac.cli ...``: the ``tlac`` command."""

import sys

from tlac.cli import main

sys.exit(main())
