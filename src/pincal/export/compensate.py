"""Compensation (Zhang et al., steps 5 and 6): the joint commands that make the calibrated robot
reach the poses a program was written for.

The calibration is what :func:`pincal.write_corrected_urdf` wrote: the corrected URDF and its
sidecar ``<stem>.calibration.json`` (the tool ``tip_T_tool`` and any extension). Commanded ``q``,
the joints reach ``q + e(q)`` (:mod:`pincal.kinematics.effects`), so the tool is at
``T(q) = FK_cal(q + e(q)) · tip_T_tool`` in the base frame. A row of commands ``q₀`` asks for
``T* = FK_nom(q₀) · tip_T_tool``, where the nominal URDF puts the same tool; a Cartesian row gives
``T*`` itself [m]. ``T(q) = T*`` is solved by damped least squares on Pinocchio's frame Jacobian of
the tool, ``Δq = Jᵀ (J Jᵀ + λ² I)⁻¹ e``, from ``q₀``, projected onto the joint limits after every
step. ``e`` is ``log6(T⁻¹ T*)`` (rotation weighted by ``rotation_weight`` [m/rad]) for the ``pose``
task, the position error for ``position``: the default after pose data and after point data, which
calibrate the measured point but not the tool's orientation. ``∂e/∂q`` is left out of ``J``
(small beside the identity; the error itself is exact). A row ends ``ok``, ``unreachable`` (no
command within the limits reaches ``T*``) or ``singular`` (the commands sit at a singularity: the
correction needs a large joint motion or cannot be made); a failed row of commands keeps them.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from pincal.data.program import Targets
from pincal.errors import DataError, NotSupportedError
from pincal.export.calibrated_robot import CalibratedRobot
from pincal.files import atomic_write
from pincal.identify.kinds import get_kind
from pincal.options import ROTATION_WEIGHT
from pincal.robot.robots import Robot

STATUSES = ("ok", "unreachable", "singular")

#: What a search found: commands, position [m] and rotation [rad] errors, iterations,
#: convergence, and σmin/σmax of the task Jacobian at the start.
_Found = tuple[np.ndarray, float, float, int, bool, float]


@dataclass(frozen=True, eq=False)
class Compensation:
    """Compensated commands and the per-row report.

    Attributes:
        joint_names: the chain's joints.
        task: ``pose`` or ``position``.
        original: (N, n) the program's commands (for a Cartesian program: the start of each row's search).
        q: (N, n) compensated commands (a failed row of commands keeps them; a failed Cartesian row
            holds the closest commands found).
        status: per row, one of :data:`STATUSES`.
        position_error: (N,) the calibrated tool's distance to the target at ``q`` [m].
        rotation_error: (N,) its orientation error [rad] (0 for the position task).
        iterations: (N,) damped least-squares iterations.
        messages: per row, why it failed ('' when ok).
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

    @property
    def ok(self) -> np.ndarray:
        """(N,) mask of the rows compensated."""
        return np.array([s == "ok" for s in self.status])

    def failures(self) -> list[str]:
        """One line per failed row: ``row R: STATUS: why`` (R counts data rows from 1)."""
        rows = zip(self.status, self.messages)
        return [f"row {i}: {s}: {m}" for i, (s, m) in enumerate(rows, start=1) if s != "ok"]


def _solve(
    cal: CalibratedRobot, target: pin.SE3, q: np.ndarray, task: str, weight: float, opts: dict[str, float]
) -> _Found:
    """Damped least squares from ``q``: the best commands met, their position [m] and rotation
    [rad] errors, iterations, convergence, and σmin/σmax of the task Jacobian at the start."""
    model, fid = cal.tool_frame
    data = model.createData()
    lo, hi = cal.robot.lower, cal.robot.upper
    q = np.clip(q, lo, hi)
    w = np.array([1.0, 1.0, 1.0, weight, weight, weight])
    ratio, it, best = 1.0, 0, (q, np.inf, np.inf)
    while True:
        pin.computeJointJacobians(model, data, cal.robot.configuration(cal.reached(q)[0]))
        pose = pin.updateFramePlacement(model, data, fid)
        pos_err = float(np.linalg.norm(target.translation - pose.translation))
        if task == "pose":
            i_m_d = pose.actInv(target)
            err = w * pin.log6(i_m_d).vector
            jac = w[:, None] * (
                pin.Jlog6(i_m_d.inverse()) @ pin.getFrameJacobian(model, data, fid, pin.LOCAL)
            )
            rot_err = float(np.linalg.norm(err[3:])) / weight
        else:
            err = target.translation - pose.translation
            jac = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)[:3]
            rot_err = 0.0
        if it == 0:
            sv = np.linalg.svd(jac, compute_uv=False)
            ratio = float(sv[-1] / sv[0]) if sv[0] > 0 else 0.0
        if pos_err + weight * rot_err < best[1] + weight * best[2]:
            best = (q, pos_err, rot_err)
        converged = pos_err <= opts["tol"] and rot_err <= opts["rot_tol"]
        if converged or it >= opts["max_iter"]:
            return (*best, it, converged, ratio)
        dq = jac.T @ np.linalg.solve(jac @ jac.T + opts["damping"] ** 2 * np.eye(len(err)), err)
        q = np.clip(q + dq * min(1.0, 0.25 / max(float(np.abs(dq).max()), 1e-12)), lo, hi)  # ≤ 0.25 a step
        it += 1


def compensate_program(
    nominal: Robot,
    calibrated: CalibratedRobot,
    program: np.ndarray | Targets,
    *,
    task: str | None = None,
    rotation_weight: float = ROTATION_WEIGHT,
    tol: float = 1e-7,
    rot_tol: float = 1e-6,
    max_iter: int = 100,
    damping: float = 1e-4,
    singular_rcond: float = 1e-3,
    max_change: float = 0.2,
    restarts: int = 8,
    seed: int = 0,
) -> Compensation:
    """Compensated commands for every row of a program (see the module docstring).

    Args:
        nominal: the URDF the program was written for (its targets, for rows of commands).
        calibrated: the calibration (see :func:`load_calibration`).
        program: joint commands (N, n) [rad or m], or :class:`Targets`.
        task: ``pose`` or ``position`` (default: ``pose`` on 6+ joints after pose data, or for
            targets with orientations; else ``position``).
        rotation_weight: weight of orientation errors [m/rad] in the pose task.
        tol: position tolerance [m]. rot_tol: orientation tolerance [rad].
        max_iter: iterations per search.
        damping: λ of the damped least squares [m].
        singular_rcond: σmin/σmax of the task Jacobian under which commands count as singular.
        max_change: largest joint change [rad or m] a row of commands may need before it counts as singular.
        restarts: random restarts for a Cartesian row the previous row's solution does not reach.
        seed: seed of the restarts.

    Raises:
        DataError: the joints differ between the robots or the program, or an unknown task.
        NotSupportedError: a pose task on a chain of fewer than 6 joints.
    """
    robot = calibrated.robot
    cartesian = isinstance(program, Targets)
    n_rows = len(program)
    q_in = _program_commands(nominal, calibrated, program, n_rows)
    task = _choose_task(calibrated, program, task)
    opts = {"tol": tol, "rot_tol": rot_tol, "max_iter": max_iter, "damping": damping}
    rng = np.random.default_rng(seed)
    out, start = q_in.copy(), q_in.copy()
    pos_e, rot_e, iters = np.zeros(n_rows), np.zeros(n_rows), np.zeros(n_rows, dtype=int)
    status, messages = ["ok"] * n_rows, [""] * n_rows
    previous = robot.random_configurations(1, rng, 0.1)[0]
    for i in range(n_rows):
        if cartesian:
            target, tries = program[i], [previous, *robot.random_configurations(restarts, rng, 0.1)]
        else:
            target, tries = nominal.frame_placement(q_in[i]) * calibrated.tool, [q_in[i]]
            outside = _beyond(robot, q_in[i], strict=True)
            if outside:
                status[i], messages[i] = "unreachable", f"the commands are beyond the limits of {outside}"
                continue
        best, start[i] = _search(calibrated, target, tries, task, rotation_weight, opts)
        q, pos_e[i], rot_e[i], iters[i], converged, ratio = best
        change = float(np.abs(q - start[i]).max())
        if converged and (cartesian or change <= max_change):
            out[i], previous = q, q
            continue
        out[i] = q if cartesian else out[i]
        off = f"{pos_e[i] * 1e3:.3f} mm" + (f", {rot_e[i] * 1e3:.3f} mrad" if task == "pose" else "")
        status[i], messages[i] = _failure(robot, q, converged, change, ratio, off, cartesian, singular_rcond)
    return Compensation(
        robot.joint_names, task, start, out, tuple(status), pos_e, rot_e, iters, tuple(messages)
    )


def _program_commands(
    nominal: Robot, calibrated: CalibratedRobot, program: np.ndarray | Targets, n_rows: int
) -> np.ndarray:
    """The program's commands (N, n) [rad or m]: zeros for a Cartesian program.

    Args:
        nominal: the URDF the program was written for.
        calibrated: the calibration.
        program: joint commands (N, n) [rad or m], or :class:`Targets`.
        n_rows: the program's number of rows.

    Raises:
        DataError: the joints differ between the robots or the program.
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
    return q_in


def _choose_task(calibrated: CalibratedRobot, program: np.ndarray | Targets, task: str | None) -> str:
    """The task asked for, or the default: ``pose`` on 6+ joints when the targets are oriented.

    Targets are oriented when a Cartesian program gives rotations, or, for a program of
    commands, when the calibration was made from pose data.

    Args:
        calibrated: the calibration.
        program: joint commands (N, n) [rad or m], or :class:`Targets`.
        task: ``pose``, ``position`` or None for the default.

    Raises:
        DataError: an unknown task.
        NotSupportedError: a pose task on a chain of fewer than 6 joints.
    """
    n_joints = calibrated.robot.n_joints
    measured = get_kind(calibrated.measure).orientation  # the sidecar's kind: its data had orientations
    oriented = program.rotations is not None if isinstance(program, Targets) else measured
    default = "pose" if oriented else "position"
    task = task or (default if n_joints >= 6 else "position")
    if task not in ("pose", "position"):
        raise DataError(f"unknown task {task!r}: use pose or position")
    if task == "pose" and n_joints < 6:
        raise NotSupportedError(f"a {n_joints}-joint chain cannot follow 6-D poses: use the position task")
    return task


def _search(
    cal: CalibratedRobot,
    target: pin.SE3,
    tries: list[np.ndarray],
    task: str,
    weight: float,
    opts: dict[str, float],
) -> tuple[_Found, np.ndarray]:
    """The best :func:`_solve` result over the starting commands ``tries``, and its start.

    The first converged search wins; otherwise the one of least ``position + weight · rotation``
    error.

    Args:
        cal: the calibration.
        target: the tool pose wanted in the base frame [m].
        tries: starting commands (n,) [rad or m], in the order tried.
        task: ``pose`` or ``position``.
        weight: weight of orientation errors [m/rad].
        opts: ``tol`` [m], ``rot_tol`` [rad], ``max_iter`` and ``damping`` [m] of :func:`_solve`.

    Returns:
        ``(q, position error [m], rotation error [rad], iterations, converged, σmin/σmax)`` of the
        best search, and the commands it started from.
    """

    def cost(found: _Found) -> float:
        return found[1] + weight * found[2]

    origin = tries[0]
    best = _solve(cal, target, origin, task, weight, opts)
    for guess in tries[1:]:
        if best[4]:  # converged: no need to try further
            break
        found = _solve(cal, target, guess, task, weight, opts)
        if found[4] or cost(found) < cost(best):
            best, origin = found, guess
    return best, origin


def _failure(
    robot: Robot,
    q: np.ndarray,
    converged: bool,
    change: float,
    ratio: float,
    off: str,
    cartesian: bool,
    singular_rcond: float,
) -> tuple[str, str]:
    """Status and message of a row not compensated.

    Args:
        robot: the calibrated chain.
        q: the closest commands found (n,) [rad or m].
        converged: whether the search reached the target.
        change: largest joint change from the start [rad or m].
        ratio: σmin/σmax of the task Jacobian at the start.
        off: how far the closest pose found is from the target, in words (mm, mrad).
        cartesian: whether the row is a Cartesian target (else a row of commands).
        singular_rcond: σmin/σmax under which commands count as singular.
    """
    if converged:
        return "singular", f"near a singularity: needs a joint change of {change:.3f} rad"
    if not cartesian and ratio < singular_rcond:
        return "singular", f"at a singularity (σmin/σmax {ratio:.1e}): {off} off"
    limit = _beyond(robot, q, strict=False)
    why = (f"; {limit} at a joint limit" if limit else "") + (
        f"; σmin/σmax {ratio:.1e} at the commands" if not cartesian and ratio < 10 * singular_rcond else ""
    )
    return "unreachable", f"out of reach: the closest pose found is {off} off{why}"


def _beyond(robot: Robot, q: np.ndarray, strict: bool) -> str:
    """Joints beyond their limits (``strict``) or at them, comma separated."""
    out = [
        j
        for j, v, a, b in zip(robot.joint_names, q, robot.lower, robot.upper)
        if (v < a or v > b) or (not strict and (v <= a or v >= b))
    ]
    return ", ".join(out)


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
