"""``pincal demo``: calibrate bundled data and print before/after tables."""

from __future__ import annotations

import argparse


def run(args: argparse.Namespace) -> int:
    """Run the command; 0 on success."""
    from pincal.demo import run

    print(run(seed=args.seed))
    return 0
