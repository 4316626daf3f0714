"""``python -m contopt``: the same as the ``contopt`` command."""

import sys

from contopt.cli import main

sys.exit(main())
