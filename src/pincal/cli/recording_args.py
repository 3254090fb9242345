"""The command line of ROS recordings: the options that read one, ``pincal extract`` and
``pincal accuracy`` (ISO 9283). Standard library only, as the rest of the parser."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from pincal.cli.numeric import real
from pincal.cli.values import vector3
from pincal.options import BUNDLED, UNITS

#: The recording options' defaults (said as ignored when given and no input is a recording).
DEFAULTS: dict[str, str | float | None] = {
    "joint_topic": "/joint_states",
    "measure_topic": None,
    "measure_frame": None,
    "time_offset": 0.0,
    "static_band": 1e-4,
    "static_time": 0.5,
}


def band(text: str) -> float:
    """``--static-band`` [rad or m]: above 0, at most 1."""
    return real(text, "the static band [rad]", 0.0, 1.0, strict=True)


def seconds(text: str) -> float:
    """``--static-time`` [s]: above 0, at most an hour."""
    return real(text, "the static time [s]", 0.0, 3600.0, strict=True)


def offset(text: str) -> float:
    """``--time-offset`` [s]: within a day either way."""
    return real(text, "the time offset [s]", -86400.0, 86400.0)


def add_recording_options(cmd: argparse.ArgumentParser, what: str = "DATA") -> None:
    """How a ROS recording given as ``what`` (DATA, PROGRAM) is read (ignored for a CSV)."""
    group = cmd.add_argument_group(
        f"ROS recordings (rosbag2 folder, .mcap, .db3 or ROS 1 .bag as {what}; not used for a CSV {what})"
    )
    group.add_argument(
        "--joint-topic", default=DEFAULTS["joint_topic"], help="the sensor_msgs/JointState topic"
    )
    group.add_argument(
        "--measure-topic", help="the Point-, Pose- or TransformStamped topic (default: the only one)"
    )
    group.add_argument("--measure-frame", metavar="PARENT:CHILD", help="measure this /tf transform")
    group.add_argument(
        "--time-offset",
        type=offset,
        default=DEFAULTS["time_offset"],
        help="added to the measurement's stamps [s] (default 0)",
    )
    group.add_argument(
        "--static-band",
        type=band,
        default=DEFAULTS["static_band"],
        help="a joint's range within a static pose [rad] (default 1e-4)",
    )
    group.add_argument(
        "--static-time",
        type=seconds,
        default=DEFAULTS["static_time"],
        help="how long a static pose lasts at least [s] (default 0.5)",
    )


def _add_force(cmd: argparse.ArgumentParser) -> None:
    cmd.add_argument("--force", action="store_true", help="replace output files that exist already")


def add_extract(sub: Any) -> None:
    """``pincal extract``."""
    ext = sub.add_parser(
        "extract",
        help="write the static poses of a ROS recording as a measurement CSV",
        usage="pincal extract [ROBOT --tip FRAME] RECORDING -o poses.csv [options]",
    )
    ext.add_argument(
        "inputs", nargs="+", metavar="[ROBOT] RECORDING", help="the robot (optional), the recording"
    )
    ext.add_argument("--tip", help="with ROBOT: the measured frame (its chain's joints are written)")
    ext.add_argument("--measure", choices=("position", "pose"), default="position", help="pose: orientations")
    ext.add_argument("-o", "--output", type=Path, required=True, help="the poses (CSV, metres and radians)")
    add_recording_options(ext)
    _add_force(ext)


def add_accuracy(sub: Any, robot_options: Any = None) -> None:
    """``pincal accuracy`` (``robot_options``: the parser's adder of how ROBOT is read)."""
    acc = sub.add_parser("accuracy", help="ISO 9283 pose accuracy and repeatability")
    acc.add_argument("robot", help=f"a .urdf or .xacro path or a bundled robot ({', '.join(BUNDLED)})")
    if robot_options is not None:
        robot_options(acc)
    acc.add_argument("data", type=Path, help="CSV with a pose column, or a recording")
    acc.add_argument("--tip", help="the measured frame (default: the robot's documented tip)")
    acc.add_argument(
        "--calibration",
        type=Path,
        help="the URDF 'calibrate -o' wrote (sidecar beside it): command through the calibrated model",
    )
    acc.add_argument("--report", type=Path, help="write the JSON report here")
    acc.add_argument("--plot", type=Path, metavar="FILE.png", help="plot the attained positions")
    acc.add_argument("--measure", choices=("position", "pose"), help="pose: orientation figures too")
    acc.add_argument("--degrees", action="store_true", help="revolute joint values are in degrees")
    acc.add_argument("--units", choices=sorted(UNITS), default="m", help="unit of x,y,z and prismatic joints")
    acc.add_argument(
        "--tool-point", type=vector3, help="without --calibration: the measured point on the tip (data units)"
    )
    acc.add_argument(
        "--pose-tolerance",
        type=band,
        default=1e-3,
        help="recordings: static poses within this of each other are one pose [rad] (default 1e-3)",
    )
    add_recording_options(acc)
    _add_force(acc)
    acc.set_defaults(lock=(), quaternion_order="wxyz", instrument_frame="base", rotation_weight=0.1)
