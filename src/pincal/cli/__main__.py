"""``python -m pincal.cli``: the ``pincal`` command."""

import sys

from . import main

sys.exit(main())
