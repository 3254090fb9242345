"""``python -m pincal.cli``: the ``pincal`` command."""

import sys

from pincal.cli import main

sys.exit(main())
