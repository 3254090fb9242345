"""The header of a measurement CSV for a robot: what a user fills to calibrate it.

The columns are those :func:`pincal.read_csv` reads (see ``docs/formats.md``): one per joint of
the chain from the base to the tip, named as in the URDF, then ``x,y,z`` (the measured point in
the instrument's frame), ``qw,qx,qy,qz`` for full-pose data, or a ``point`` column for fixed
points. Comment lines (``#``) above the header say the units the values must be in.
"""

from __future__ import annotations

from collections.abc import Mapping

from pincal.identify.kinds import get_kind
from pincal.robot.robots import Robot


def csv_template(
    robot: Robot,
    kind: str = "position",
    units: str = "m",
    degrees: bool = False,
    markers: Mapping[str, str] | None = None,
) -> str:
    """The comment lines and header of a measurement CSV for ``robot``'s chain.

    Args:
        robot: the chain (:func:`pincal.load_robot`): its joints name the joint columns.
        kind: ``position`` (x,y,z), ``pose`` (x,y,z and qw,qx,qy,qz) or ``points`` (a point column).
        units: ``m`` or ``mm``: the unit of x,y,z and of prismatic joint values.
        degrees: revolute joint values in degrees (else radians).
        markers: several markers per pose: each label's frame (columns ``xK,yK,zK``), in order.

    Returns:
        The text of the file: ``#`` lines on units and options, then the header line.
    """
    angle = "degrees (pass degrees=True)" if degrees else "radians"
    length = "millimetres (pass units=mm)" if units == "mm" else "metres"
    prismatic = [j for j, p in zip(robot.joint_names, robot.prismatic) if p]
    lines = [
        f"# pincal measurement CSV: {robot.name}, chain to {robot.tip}; one row per pose, values "
        "comma separated",
        "# rows in the order the robot visited the poses (a joint's lost motion is read from it)",
        f"# joint columns: the commanded joint values; revolute joints in {angle}"
        + (f"; prismatic joints ({', '.join(prismatic)}) in {length}" if prismatic else ""),
    ]
    measure = get_kind(kind)
    columns = measure.columns
    if markers:
        lines += marker_lines(markers, length)
        columns = tuple(f"{a}{k}" for k in markers for a in "xyz")
    elif measure.fixed_points:
        lines.append("# point: the name or number of the fixed point (socket) the tip is held at")
    else:
        lines.append(
            f"# x,y,z: the measured position of a point fixed on {robot.tip} (a reflector, a marker), "
            f"in the instrument's frame, in {length}"
        )
    if measure.orientation:
        lines.append("# qw,qx,qy,qz: the measured orientation (unit quaternion) in the instrument's frame")
    if not measure.fixed_points:
        lines += [
            "# noise: to judge what the calibration leaves, give calibrate the instrument's noise as "
            "noise_mm=MM, RMS per axis in mm",
            "#   (a datasheet's accuracy U at 2 sigma, per axis: U/2; for the 3-D point error, as an MPE: "
            "U/(2*sqrt(3)); or measure a few poses twice)",
        ]
    lines.append(",".join((*robot.joint_names, *columns)))
    return "\n".join(lines) + "\n"


def marker_lines(markers: Mapping[str, str], length: str) -> list[str]:
    """The comment lines that say what each marker's columns hold."""
    each = "; ".join(f"{k} on {frame}" for k, frame in markers.items())
    return [
        f"# xK,yK,zK: the measured position of marker K, a point fixed on its frame ({each}), in the "
        f"instrument's frame, in {length}",
        "# leave a marker's three cells empty in a row where it was not seen",
    ]
