"""Compensation (Zhang et al., steps 5 and 6): the joint commands that make the calibrated robot
reach the poses a program was written for.

The calibration is the full model :func:`load_calibration` reads from what
:func:`pincal.write_corrected_urdf` wrote (the URDF, the sidecar's ``complete`` and effects). Commanded
``q``, the joints reach what :meth:`CalibratedRobot.reached` says (``q + e(q)``, lost motion from
the compensated commands of the rows before, as the robot runs them), and
the tool is at ``T(q) = FK_cal(reached) · tip_T_tool`` in the base frame. A row of commands ``q₀``
asks for ``T* = FK_nom(q₀) · tip_T_tool``: the point *and the orientation* the nominal URDF gave
the tool (the ``pose`` task, the default), or the point only (``position``: the orientation then
moves, and :attr:`Compensation.rotation_error` says by how much). A Cartesian row gives ``T*``
itself [m] (its orientation, when the row has one).

Each row is solved from ``q₀`` (a Cartesian row: from the previous row's solution, then random
restarts) by :mod:`pincal.export.inverse_kinematics`: the point first, then the orientation (on a
chain of fewer than six joints, as close as it can be), then the smallest joint change from
``q₀``. A row ends ``ok``, ``unreachable`` (no command within the limits reaches ``T*``: beyond a
limit, or beyond what the calibrated arm reaches) or ``singular`` (the commands sit at or near a
singularity: the correction needs a large joint motion or cannot be made); a failed row of
commands keeps them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pinocchio as pin

from pincal.data.program import Targets
from pincal.errors import DataError
from pincal.export.calibrated_robot import CalibratedRobot
from pincal.export.inverse_kinematics import Approach, Settings, search, solve, tool_errors
from pincal.export.refusals import beyond, in_play, unreached
from pincal.files import atomic_write
from pincal.robot.robots import Robot

STATUSES = ("ok", "unreachable", "singular")
#: What a program can ask: the tool's whole pose (the default), or its point only.
TASKS = ("pose", "position")


@dataclass(frozen=True, eq=False)
class Compensation:
    """Compensated commands and the per-row report.

    Attributes:
        joint_names: the chain's joints.
        task: ``pose`` (point and orientation) or ``position`` (point only).
        original: (N, n) the program's commands (for a Cartesian program: the start of each row's search).
        q: (N, n) compensated commands (a failed row of commands keeps them; a failed Cartesian row
            holds the closest commands found).
        status: per row, one of :data:`STATUSES`.
        position_error: (N,) the calibrated tool's distance to the target at ``q`` [m].
        rotation_error: (N,) the angle between the calibrated tool's orientation at ``q`` and the
            target's [rad]: for the ``position`` task, how far the orientation moved; NaN for
            Cartesian targets without orientations.
        iterations: (N,) Gauss-Newton iterations.
        messages: per row, why it failed ('' when ok).
        prismatic: per joint, True when it is prismatic (its changes are in metres).
        cartesian: whether the program gave Cartesian targets (else rows of commands).
    """

    joint_names: tuple[str, ...]
    task: str
    original: np.ndarray
    q: np.ndarray
    status: tuple[str, ...]
    position_error: np.ndarray
    rotation_error: np.ndarray
    iterations: np.ndarray
    messages: tuple[str, ...]
    prismatic: tuple[bool, ...] = ()
    cartesian: bool = False

    @property
    def ok(self) -> np.ndarray:
        """(N,) mask of the rows compensated."""
        return np.array([s == "ok" for s in self.status], dtype=bool)

    @property
    def joint_change(self) -> np.ndarray:
        """(N, n) compensated minus original commands [rad or m] (zero on a failed row of commands)."""
        return self.q - self.original

    def failures(self) -> list[str]:
        """One line per failed row: ``row R: STATUS: why`` (R counts data rows from 1)."""
        rows = zip(self.status, self.messages)
        return [f"row {i}: {s}: {m}" for i, (s, m) in enumerate(rows, start=1) if s != "ok"]

    def summary(self) -> str:
        """One line: rows compensated; over them, the worst distance of the point and the worst
        turn of the orientation from the target, and (for rows of commands) the largest joint change."""
        ok = self.ok
        head = f"compensated {int(ok.sum())} of {len(self.status)} rows ({self.task} task)"
        if not ok.any():
            return head
        pos, rot = self.position_error[ok].max() * 1e3, self.rotation_error[ok].max()
        target = "the targets" if self.cartesian else "where the nominal URDF put it"
        if np.isnan(rot):
            words = f"the point within {pos:.2g} mm of {target}"
        elif self.task == "pose":
            n = len(self.joint_names)
            close = f" (as close as {n} joints allow)" if n < 6 else ""
            pose = "the targets" if self.cartesian else "the pose the nominal URDF gave it"
            words = f"the tool within {pos:.2g} mm and {rot * 1e3:.2g} mrad{close} of {pose}"
        else:
            words = (
                f"the point within {pos:.2g} mm of {target}; the orientation is not kept: it turned "
                f"by up to {rot * 1e3:.3f} mrad ({math.degrees(rot):.3f}°)"
            )
        return f"{head}: {words}{'' if self.cartesian else self._change_words()}"

    def _change_words(self) -> str:
        """``; largest joint change ...`` over the rows compensated (revolute, then prismatic)."""
        change = np.abs(self.joint_change[self.ok])
        slide = np.array(self.prismatic or [False] * len(self.joint_names), dtype=bool)
        words = []
        if (~slide).any():
            turn = float(change[:, ~slide].max())
            words.append(f"{turn * 1e3:.3f} mrad ({math.degrees(turn):.3f}°)")
        if slide.any():
            words.append(f"{float(change[:, slide].max()) * 1e3:.4f} mm (prismatic)")
        return "; largest joint change " + ", ".join(words)


def compensate_program(
    nominal: Robot,
    calibrated: CalibratedRobot,
    program: np.ndarray | Targets,
    *,
    task: str | None = None,
    tol: float = 1e-9,
    rot_tol: float = 1e-9,
    max_iter: int = 30,
    rcond: float = 1e-8,
    singular_rcond: float = 1e-2,
    max_change: float = 0.2,
    max_step: float = 0.5,
    damping: float = 0.03,
    restarts: int = 8,
    seed: int = 0,
) -> Compensation:
    """Compensated commands for every row of a program (see the module docstring).

    Args:
        nominal: the URDF the program was written for (its targets, for rows of commands).
        calibrated: the calibration (see :func:`load_calibration`).
        program: joint commands (N, n) [rad or m], or :class:`Targets`.
        task: ``pose`` (the point and the orientation; the default, but for Cartesian targets
            without orientations) or ``position`` (the point only; the orientation moves).
        tol: position tolerance [m]. rot_tol: orientation tolerance [rad].
        max_iter: iterations per search (each of the two, plain and careful).
        rcond: singular values of a task's Jacobian below ``rcond`` times its largest are left out.
        singular_rcond: σmin/σmax of the task Jacobian (orientation rows weighted by
            :data:`~pincal.options.ROTATION_WEIGHT`) under which commands count as singular.
        max_change: largest joint change [rad or m] a row of commands may need before it counts as singular.
        max_step: largest joint change [rad or m] of one iteration.
        damping: the first λ of the Levenberg-Marquardt search [m/rad] (where Gauss-Newton fails).
        restarts: random restarts for a Cartesian row the previous row's solution does not reach.
        seed: seed of the restarts.

    Raises:
        DataError: the joints differ between the robots or the program, an unknown task, or a
            pose task on Cartesian targets without orientations.
    """
    robot = calibrated.robot
    cartesian = isinstance(program, Targets)
    n_rows = len(program)
    q_in, targets = _program_commands(nominal, calibrated, program, n_rows)
    opts = Settings(_choose_task(program, task), tol, rot_tol, max_iter, rcond, max_step, damping)
    rng = np.random.default_rng(seed)
    out, start = q_in.copy(), q_in.copy()
    iters = np.zeros(n_rows, dtype=int)
    status, messages = ["ok"] * n_rows, [""] * n_rows
    before = Approach()  # where the robot comes from: the rows written before, run in order
    for i in range(n_rows):
        if cartesian:
            seeds = robot.random_configurations(restarts + 1, rng, 0.1)
            tries = [seeds[0] if before.previous is None else before.previous, *seeds[1:]]
            best = search(calibrated, targets[i], tries, before, opts)
            out[i], start[i], iters[i] = best.q, best.start, best.iterations
            if not best.converged:
                status[i], messages[i] = unreached(robot, best, opts.task, None)
        else:
            row = _command_row(calibrated, targets[i], q_in[i], before, opts, (singular_rcond, max_change))
            out[i], iters[i], status[i], messages[i] = row
            messages[i] += in_play(calibrated, q_in[max(i - 1, 0) : i + 1]) if row[2] != "ok" else ""
        before = before.then(out[i])
    pos_e, rot_e = tool_errors(calibrated, targets, out)
    if cartesian and getattr(program, "rotations", None) is None:
        rot_e[:] = np.nan  # no orientation asked for
    report = (tuple(status), pos_e, rot_e, iters, tuple(messages))
    return Compensation(robot.joint_names, opts.task, start, out, *report, tuple(robot.prismatic), cartesian)


def _command_row(
    cal: CalibratedRobot,
    target: pin.SE3,
    q0: np.ndarray,
    before: Approach,
    opts: Settings,
    limits: tuple[float, float],
) -> tuple[np.ndarray, int, str, str]:
    """One row of commands ``q0`` (n,): the commands to write, the iterations, status and message.

    Args:
        cal: the calibration.
        target: where the nominal URDF put the tool with ``q0`` [m].
        q0: the row's commands [rad or m].
        before: where the robot comes from: the commands written for the rows before.
        opts: the search's settings.
        limits: ``(singular_rcond, max_change)`` of :func:`compensate_program`.
    """
    outside = beyond(cal.robot, q0, strict=True)
    if outside:
        return q0, 0, "unreachable", f"the commands are beyond the limits of {outside}"
    prev = before.previous  # also tried from there: a row the program repeats, reached again
    tries = [q0] if prev is None or float(np.abs(prev - q0).max()) > limits[1] else [q0, prev]
    best = search(cal, target, tries, before, opts)
    if best.converged and float(np.abs(best.q - q0).max()) <= limits[1]:
        return best.q, best.iterations, "ok", ""
    status, message = unreached(cal.robot, best, opts.task, limits)
    if opts.task == "pose":  # what the position task would do instead
        point = solve(cal, target, q0, before, replace(opts, task="position"))
        if point.converged and float(np.abs(point.q - q0).max()) <= limits[1]:
            message += (
                f" (the position task reaches the point, the orientation {point.rotation * 1e3:.3f} mrad off)"
            )
    return q0, best.iterations, status, message


def _program_commands(
    nominal: Robot, calibrated: CalibratedRobot, program: np.ndarray | Targets, n_rows: int
) -> tuple[np.ndarray, Targets | list[pin.SE3]]:
    """The program's commands (N, n) [rad or m] (zeros for a Cartesian program), and its targets:
    where the nominal URDF put the tool with each row of commands, or the Cartesian targets.

    Raises:
        DataError: the joints differ between the robots (``nominal``, the calibration's) or the program.
    """
    robot = calibrated.robot
    if isinstance(program, Targets):
        q_in = np.zeros((n_rows, robot.n_joints))
    else:
        q_in = np.atleast_2d(np.asarray(program, float))
    if nominal.joint_names != robot.joint_names or q_in.shape[1] != robot.n_joints:
        raise DataError(
            f"the program and the nominal robot must have the calibration's joints {robot.joint_names}"
        )
    if isinstance(program, Targets):
        return q_in, program
    return q_in, [nominal.frame_placement(q) * calibrated.tool for q in q_in]


def _choose_task(program: np.ndarray | Targets, task: str | None) -> str:
    """The task asked for, or the default: ``pose``, but ``position`` for Cartesian targets
    without orientations (``task`` None).

    Raises:
        DataError: an unknown task, or the pose task for targets without orientations.
    """
    unoriented = isinstance(program, Targets) and program.rotations is None
    task = task or ("position" if unoriented else "pose")
    if task not in TASKS:
        raise DataError(f"unknown task {task!r}: use pose or position")
    if task == "pose" and unoriented:
        raise DataError(
            "the pose task needs the targets' orientations (qw,qx,qy,qz columns): give them, or use "
            "the position task"
        )
    return task


def write_program(
    path: str | Path,
    result: Compensation,
    degrees: bool = False,
    prismatic: tuple[bool, ...] | None = None,
    units: str = "m",
) -> None:
    """Write the compensated commands and a ``status`` column, atomically, in the program's units:
    revolute joints in radians (degrees with ``degrees``), prismatic ones in ``units``
    (:func:`pincal.units.joints_to_file`)."""
    from pincal.units import joints_to_file

    q = joints_to_file(result.q, degrees, units, prismatic)
    lines = [",".join([*result.joint_names, "status"])]
    lines += [",".join([*(repr(float(v)) for v in row), s]) for row, s in zip(q, result.status)]
    atomic_write(path, "\n".join(lines) + "\n")
