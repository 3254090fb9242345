"""``pincal calibrate``'s ``--prior`` and ``--force-fit``: the pull toward the URDF and the guard
(:class:`pincal.identify.guard.Pull`)."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from pincal.identify.guard import Pull


def pull(args: argparse.Namespace) -> Pull:
    """The :class:`~pincal.identify.guard.Pull` the options ask for (the weight is checked by the fit)."""
    from pincal.identify.guard import Pull  # here: --help loads no NumPy

    return Pull(args.prior, args.force_fit)


def add_pull_options(cal: argparse.ArgumentParser) -> None:
    """``--prior`` and ``--force-fit`` of ``pincal calibrate`` (issue 31: :mod:`pincal.identify.prior`,
    :mod:`pincal.identify.guard`)."""
    cal.add_argument(
        "--prior",
        default="auto",
        metavar="auto|WEIGHT",
        help="pull of the geometric corrections toward the URDF: 'auto' (default) chooses its weight by "
        "maximum evidence on the data; or a weight per natural unit (0.1 m of correction weighs as a "
        "residual of 0.1 m x WEIGHT)",
    )
    cal.add_argument(
        "--force-fit",
        action="store_true",
        help="export the fit even when its leave-one-out validation is not reliably better than the "
        "nominal model's (by default the nominal geometry is then exported, said in the summary)",
    )
