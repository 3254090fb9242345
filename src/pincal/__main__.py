"""``python -m pincal``: the ``pincal`` command."""

import sys

from .cli import main

sys.exit(main())
