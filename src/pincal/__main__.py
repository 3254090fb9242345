"""``python -m pincal``: the ``pincal`` command."""

import sys

from pincal.cli import main

sys.exit(main())
