"""Data options of ``pincal calibrate`` that ``tcp`` and ``compensate`` take too, where they
apply: ``tcp --robot ... --lock`` (chain joints held at neutral when the flange poses are
computed) and ``compensate --quaternion-order`` (the program's target quaternions). The others
(``--measure``, ``--point-distance``, ``--model``, ``--loss``, ...) describe a calibration's
measurements: both commands refuse them as unknown options (one ``pincal: error:`` line, exit 2).
"""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from pincal.cli.values import name_list
from pincal.errors import DataError
from pincal.options import QUATERNION_ORDERS

if TYPE_CHECKING:
    from pincal.robot.robots import Robot


def add_lock(cmd: argparse.ArgumentParser) -> None:
    """``--lock JOINT,...`` for ``tcp`` (with ``--robot``)."""
    cmd.add_argument(
        "--lock",
        type=name_list,
        default=(),
        metavar="JOINT,...",
        help="with --robot: chain joints held at neutral (as calibrate's --lock); the file needs no column "
        "for them",
    )


def add_program_quaternion_order(cmd: argparse.ArgumentParser) -> None:
    """``--quaternion-order`` for ``compensate`` (its targets' ``qw,qx,qy,qz`` columns)."""
    _add_quaternion_order(cmd, "the target columns", "as calibrate's option")


def _add_quaternion_order(cmd: argparse.ArgumentParser, columns: str, xyzw_for: str) -> None:
    """``--quaternion-order``: which of ``columns`` qw,qx,qy,qz hold what (``xyzw_for``: when the
    other order is the one to give)."""
    cmd.add_argument(
        "--quaternion-order",
        choices=QUATERNION_ORDERS,
        default="wxyz",
        help=f"wxyz (default): {columns} qw,qx,qy,qz hold what their names say; xyzw: the four "
        f"quaternion columns, left to right, hold x, y, z, w ({xyzw_for})",
    )


def check_lock(chain: Robot, lock: tuple[str, ...]) -> None:
    """Refuse ``--lock`` joints that are not on ``chain``.

    Raises:
        DataError: a locked joint not between the base and the tip.
    """
    unknown = [j for j in lock if j not in chain.joint_names]
    if unknown:
        raise DataError(
            f"--lock {','.join(unknown)}: not joints between the base and {chain.tip} "
            f"({', '.join(chain.joint_names)})"
        )


def add_plausibility_options(cmd: argparse.ArgumentParser) -> None:
    """``--quaternion-order`` and ``--accept-implausible``, shared by the data-reading commands."""
    _add_quaternion_order(cmd, "the columns", "data exported as x,y,z,w")
    cmd.add_argument(
        "--accept-implausible",
        action="store_true",
        help="keep a result that no rigid arm can be (a warning instead of an error)",
    )
