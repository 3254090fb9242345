"""Outside audit of the residual verdict and of the named cause, with an independent simulator.

This benchmark does not import pincal: it simulates measurements with Pinocchio alone and runs
``pincal calibrate`` and ``pincal diagnose`` as an outside user would (subprocess, CSV in, JSON out,
as ``contracts.md`` specifies).

Simulation (per robot, seed and effect):

* the robot is the example-robot-data URDF (``ur5``: tip ``tool0``; ``panda``: tip ``panda_hand_tcp``,
  finger joints locked); the "true" robot perturbs every chain joint's placement (0.5 mm and 0.5 mrad
  std per axis) and every joint's zero (1 mrad std);
* an unknown instrument registration (random rotation, ~1 m translation) and an unknown measured point
  5 cm from the tip frame;
* random commanded configurations within the joint limits (the outer 5 % of each range avoided);
* measured point = instrument_T_base * oMf(tip) * tool_point + Gaussian noise (``--sigma`` mm per axis,
  default 0.05).

Effects added to the truth, each scaled so that the RMS over the poses of the norm of its displacement
of the measured point is M times the noise floor (sqrt(3) * sigma), M in ``--multiples``:

* ``rigid``: none (the control; it does not depend on M and is run once);
* ``bending``: the upper arm bends like a cantilever under gravity: the elbow is displaced perpendicular
  to the link in proportion to the gravity component across it, tilts by 1.5 * deflection / length
  about the horizontal axis across the link, and shortens in proportion to the gravity component along
  it (a point displacement, in base coordinates, of everything beyond the elbow);
* ``drift``: the instrument drifts along a fixed random direction linearly with the pose index (centred
  on the middle of the session: a constant offset is the registration, not an effect);
* ``sin3``: a joint error a * sin(3 q + phase) on a middle joint (pincal lists harmonics 1 and 2 only);
* ``cubic``: a joint error proportional to the cube of the gravity torque of a loaded joint;
* ``pair``: two listed effects at once: a gear harmonic of order 1 on the elbow and an encoder scale on
  a wrist joint (each scaled to M times the floor on its own).

Joint effects are applied to the joint angle before the forward kinematics (q_reached = q_cmd + offset
+ error); gravity torques come from ``pin.computeGeneralizedGravity`` on the true model.

For each effect the script also computes, with a linearised model of its own (numerical Jacobians of
the measured point in the 6 placement parameters of every joint, the 6 of the registration and the 3 of
the tool point), what no rigid model can absorb (``rigid_rest``: the RMS per pose of the component of
the displacement orthogonal to the rigid Jacobian) and what neither the rigid model nor the best single
listed effect (compliance, harmonic 1 or 2, encoder scale, backlash on any joint) can absorb
(``listed_rest``). These are the references an ideal calibrator would leave, noise aside.

Runs, per robot x effect x M x N (``--poses``) x seed: ``pincal calibrate ROBOT data.csv --noise SIGMA
--test truth.csv --report r.json`` and ``pincal diagnose ROBOT data.csv --noise SIGMA --json d.json``.
Recorded: exit codes, times, the residual verdict and ``unexplained_mm``, the causes calibrate kept
(the report's ``choice.cause`` / ``extension``) and the cause diagnose named, and any "implausible"
flag in either JSON.

Acceptance (printed at the end; exit status 1 when one fails):

1. every rigid control: verdict ``explained``;
2. every outside effect (bending, drift, sin3, cubic) at M >= 3: verdict ``unexplained`` and
   ``unexplained_mm`` within a factor 2 of the true RMS of the structure the final model leaves
   (``left``: the calibrated model's error against the noise-free truth on the same poses, given to
   ``calibrate`` as ``--test``, which scores and never fits). ``unexplained_mm`` is defined as what
   the final model leaves above the noise; when a listed cause stands in for part of an outside
   effect, that is less than the effect's whole RMS (``struct``), which the ratios print beside it;
3. the pair: both listed effects named (by calibrate), or verdict ``unexplained``;
4. calibrate and diagnose name the same cause (the same first cause, or both none);
5. no run exits with a status other than 0.

Usage::

    python benchmarks/verdict_audit.py [--quick] [--robots ur5 panda] [--poses 60 100]
        [--multiples 3 6 10] [--seeds 1] [--sigma 0.05] [--jobs 1] [--json FILE] [--keep DIR]

``--quick``: ur5 only, N = 60, M in {3, 10}, one seed.
"""

from __future__ import annotations

import argparse
import csv
import importlib.metadata
import json
import os
import shlex
import subprocess
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

ROBOTS_DIR = Path(
    str(
        importlib.metadata.distribution("example-robot-data").locate_file(
            "cmeel.prefix/share/example-robot-data/robots"
        )
    )
)

OUTSIDE = ("bending", "drift", "sin3", "cubic")
EFFECTS = ("rigid", *OUTSIDE, "pair")
TIMEOUT_S = 600.0
PINCAL = ["pincal"]  # the command; --pincal replaces it (e.g. "python -m pincal" on a snapshot's PYTHONPATH)


@dataclass(frozen=True)
class RobotSpec:
    """A robot of the audit: its URDF, tip, and the joints the effects act on."""

    name: str
    urdf: str
    tip: str
    fallback_tip: str
    locked: tuple[str, ...]
    bend_from: str  # the bending segment runs from this joint's origin ...
    bend_to: str  # ... to this one's (everything beyond it moves with the bent end)
    mid_joint: str  # sin(3q) and the order-1 harmonic of the pair
    loaded_joint: str  # cubic stiffness
    wrist_joint: str  # encoder scale of the pair


SPECS = {
    "ur5": RobotSpec(
        "ur5",
        "ur_description/urdf/ur5_robot.urdf",
        "tool0",
        "tool0",
        (),
        "shoulder_lift_joint",
        "elbow_joint",
        "elbow_joint",
        "shoulder_lift_joint",
        "wrist_1_joint",
    ),
    "panda": RobotSpec(
        "panda",
        "panda_description/urdf/panda.urdf",
        "panda_hand_tcp",
        "panda_link8",
        ("panda_finger_joint1", "panda_finger_joint2"),
        "panda_joint2",
        "panda_joint4",
        "panda_joint4",
        "panda_joint2",
        "panda_joint6",
    ),
}


# --------------------------------------------------------------------------------------------------
# The simulator (Pinocchio only)
# --------------------------------------------------------------------------------------------------


@dataclass
class Robot:
    """The nominal model of a robot, reduced to its chain, and its tip frame."""

    spec: RobotSpec
    model: pin.Model
    tip: str
    joints: list[str]

    @classmethod
    def load(cls, spec: RobotSpec) -> Robot:
        """Read the URDF with Pinocchio and lock the joints that are not in the CSV."""
        full = pin.buildModelFromUrdf(str(ROBOTS_DIR / spec.urdf))
        locked = [full.getJointId(name) for name in spec.locked if full.existJointName(name)]
        model = pin.buildReducedModel(full, locked, pin.neutral(full)) if locked else full
        tip = spec.tip if model.existFrame(spec.tip) else spec.fallback_tip
        joints = [model.names[j] for j in range(1, model.njoints)]
        if model.nq != len(joints):
            raise RuntimeError(f"{spec.name}: only 1-DoF joints are supported")
        return cls(spec, model, tip, joints)

    def joint_index(self, name: str) -> int:
        """Index of a joint in q (0-based)."""
        return self.joints.index(name)

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """``n`` random configurations within the limits, the outer 5 % of each range avoided."""
        lo = np.asarray(self.model.lowerPositionLimit, dtype=float)
        hi = np.asarray(self.model.upperPositionLimit, dtype=float)
        margin = 0.05 * (hi - lo)
        return rng.uniform(lo + margin, hi - margin, size=(n, self.model.nq))


@dataclass
class Truth:
    """A "true" robot: perturbed joint placements and zeros, the registration and the tool point."""

    model: pin.Model
    offsets: np.ndarray
    instrument_T_base: pin.SE3
    tool: np.ndarray
    tip_id: int
    data: pin.Data = field(init=False)

    def __post_init__(self) -> None:
        self.data = self.model.createData()

    @classmethod
    def draw(cls, robot: Robot, rng: np.random.Generator) -> Truth:
        """Perturb the nominal robot and draw the unknown registration and tool point."""
        model = pin.Model(robot.model)
        for j in range(1, model.njoints):
            twist = np.concatenate([rng.normal(0.0, 0.5e-3, 3), rng.normal(0.0, 0.5e-3, 3)])
            model.jointPlacements[j] = model.jointPlacements[j] * pin.exp6(pin.Motion(twist))
        offsets = rng.normal(0.0, 1e-3, model.nq)
        quat = rng.normal(size=4)
        quat /= np.linalg.norm(quat)
        rotation = pin.Quaternion(quat[0], quat[1], quat[2], quat[3]).toRotationMatrix()
        direction = rng.normal(size=3)
        translation = direction / np.linalg.norm(direction) * rng.uniform(0.8, 1.5)
        tool_dir = rng.normal(size=3)
        tool = tool_dir / np.linalg.norm(tool_dir) * 0.05
        return cls(model, offsets, pin.SE3(rotation, translation), tool, model.getFrameId(robot.tip))

    def points(
        self,
        q: np.ndarray,
        model: pin.Model | None = None,
        registration: pin.SE3 | None = None,
        tool: np.ndarray | None = None,
    ) -> np.ndarray:
        """Measured points (N, 3), instrument frame, metres, without noise, for reached angles ``q``."""
        model = self.model if model is None else model
        data = self.data if model is self.model else model.createData()
        registration = self.instrument_T_base if registration is None else registration
        tool = self.tool if tool is None else tool
        out = np.empty((len(q), 3))
        for i, qi in enumerate(q):
            pin.framesForwardKinematics(model, data, qi)
            out[i] = registration.act(data.oMf[self.tip_id].act(tool))
        return out

    def base_points(self, q: np.ndarray) -> np.ndarray:
        """Measured points (N, 3) in the base frame for reached angles ``q``."""
        out = np.empty((len(q), 3))
        for i, qi in enumerate(q):
            pin.framesForwardKinematics(self.model, self.data, qi)
            out[i] = self.data.oMf[self.tip_id].act(self.tool)
        return out

    def gravity(self, q: np.ndarray) -> np.ndarray:
        """Gravity torques (N, nq) of the true model, N·m."""
        return np.array([pin.computeGeneralizedGravity(self.model, self.data, qi) for qi in q])

    def joint_origins(self, q: np.ndarray, joint_id: int) -> np.ndarray:
        """Positions (N, 3), base frame, of a joint's origin."""
        out = np.empty((len(q), 3))
        for i, qi in enumerate(q):
            pin.forwardKinematics(self.model, self.data, qi)
            out[i] = self.data.oMi[joint_id].translation
        return out


def rms_norm(displacement: np.ndarray) -> float:
    """RMS over the poses of the norm of a (N, 3) displacement, in the displacement's unit."""
    return float(np.sqrt(np.mean(np.sum(displacement**2, axis=1))))


@dataclass
class Effect:
    """A hidden effect: its displacement of the measured point (instrument frame, metres) per pose,
    and the listed (effect, joint) pairs it is made of (empty for an outside effect)."""

    name: str
    displacement: np.ndarray
    listed: list[tuple[str, str]]
    detail: str


def joint_effect(
    truth: Truth, q_reached: np.ndarray, shapes: dict[int, np.ndarray], target_m: float
) -> tuple[np.ndarray, np.ndarray]:
    """Joint errors (N, nq) made of per-joint shapes, each scaled so that its own displacement of the
    measured point has an RMS norm of ``target_m``; and the total displacement (N, 3)."""
    base = truth.points(q_reached)
    errors = np.zeros_like(q_reached)
    for j, shape in shapes.items():
        unit = shape / np.sqrt(np.mean(shape**2))
        probe = np.zeros_like(q_reached)
        probe[:, j] = 1e-5 * unit
        small = rms_norm(truth.points(q_reached + probe) - base)
        errors[:, j] = 1e-5 * unit * target_m / small
    return errors, truth.points(q_reached + errors) - base


def make_effect(
    name: str, robot: Robot, truth: Truth, q_reached: np.ndarray, target_m: float, rng: np.random.Generator
) -> tuple[Effect, np.ndarray]:
    """The effect ``name`` at ``target_m`` RMS: its displacement and the joint errors it adds."""
    spec = robot.spec
    n = len(q_reached)
    zero = np.zeros_like(q_reached)
    if name == "rigid":
        return Effect(name, np.zeros((n, 3)), [], "none"), zero
    if name == "drift":
        direction = rng.normal(size=3)
        direction /= np.linalg.norm(direction)
        t = np.arange(n) / (n - 1) - 0.5
        shape = t[:, None] * direction[None, :]
        disp = shape * target_m / rms_norm(shape)
        rate = target_m / rms_norm(shape) * 1e3 / n
        return Effect(name, disp, [], f"{rate:.4f} mm per pose along a fixed direction"), zero
    if name == "bending":
        a = truth.model.getJointId(spec.bend_from)
        b = truth.model.getJointId(spec.bend_to)
        p_a = truth.joint_origins(q_reached, a)
        p_b = truth.joint_origins(q_reached, b)
        link = p_b - p_a
        length = np.linalg.norm(link, axis=1, keepdims=True)
        u = link / length
        g = np.array([0.0, 0.0, -1.0])
        along = u @ g
        across = g[None, :] - along[:, None] * u
        tilt = 1.5 / length * np.cross(u, across)
        tip = truth.base_points(q_reached)
        shape_base = across + 0.3 * along[:, None] * u + np.cross(tilt, tip - p_b)
        shape = shape_base @ truth.instrument_T_base.rotation.T
        disp = shape * target_m / rms_norm(shape)
        return Effect(name, disp, [], f"cantilever {spec.bend_from}->{spec.bend_to}"), zero
    if name == "sin3":
        j = robot.joint_index(spec.mid_joint)
        phase = rng.uniform(0, 2 * np.pi)
        errors, disp = joint_effect(truth, q_reached, {j: np.sin(3 * q_reached[:, j] + phase)}, target_m)
        amp = float(np.max(np.abs(errors[:, j])))
        return Effect(name, disp, [], f"{spec.mid_joint}: {amp * 1e3:.3f} mrad sin(3q)"), errors
    if name == "cubic":
        j = robot.joint_index(spec.loaded_joint)
        tau = truth.gravity(q_reached)[:, j]
        # the joint sags under its load (the error opposes the holding torque), stiffer as it loads
        errors, disp = joint_effect(truth, q_reached, {j: -(tau**3)}, target_m)
        amp = float(np.max(np.abs(errors[:, j])))
        detail = (
            f"{spec.loaded_joint}: torque^3, max {amp * 1e3:.3f} mrad, |tau| <= {np.max(np.abs(tau)):.0f} N·m"
        )
        return Effect(name, disp, [], detail), errors
    if name == "pair":
        jh = robot.joint_index(spec.mid_joint)
        js = robot.joint_index(spec.wrist_joint)
        phase = rng.uniform(0, 2 * np.pi)
        mid = 0.5 * (robot.model.lowerPositionLimit[js] + robot.model.upperPositionLimit[js])
        shapes = {jh: np.sin(q_reached[:, jh] + phase), js: q_reached[:, js] - mid}
        errors, disp = joint_effect(truth, q_reached, shapes, target_m)
        listed = [("gear_harmonic", spec.mid_joint), ("encoder_scale", spec.wrist_joint)]
        detail = f"harmonic1 {spec.mid_joint} + scale {spec.wrist_joint}"
        return Effect(name, disp, listed, detail), errors
    raise ValueError(name)


# --------------------------------------------------------------------------------------------------
# What an ideal calibrator could absorb (linearised, noise-free)
# --------------------------------------------------------------------------------------------------


def rigid_jacobian(truth: Truth, q_reached: np.ndarray, eps: float = 1e-6) -> np.ndarray:
    """Jacobian (3N, 6 * njoints + 9) of the measured points in the joint placements (local twists), the
    registration (a twist on the left) and the tool point, by central differences."""
    columns: list[np.ndarray] = []

    def diff(plus: np.ndarray, minus: np.ndarray) -> None:
        columns.append(((plus - minus) / (2 * eps)).ravel())

    for j in range(1, truth.model.njoints):
        original = truth.model.jointPlacements[j].copy()
        for k in range(6):
            twist = np.zeros(6)
            twist[k] = eps
            model = pin.Model(truth.model)
            model.jointPlacements[j] = original * pin.exp6(pin.Motion(twist))
            plus = truth.points(q_reached, model=model)
            model.jointPlacements[j] = original * pin.exp6(pin.Motion(-twist))
            diff(plus, truth.points(q_reached, model=model))
    for k in range(6):
        twist = np.zeros(6)
        twist[k] = eps
        plus = truth.points(q_reached, registration=pin.exp6(pin.Motion(twist)) * truth.instrument_T_base)
        minus = truth.points(q_reached, registration=pin.exp6(pin.Motion(-twist)) * truth.instrument_T_base)
        diff(plus, minus)
    for k in range(3):
        step = np.zeros(3)
        step[k] = eps
        diff(truth.points(q_reached, tool=truth.tool + step), truth.points(q_reached, tool=truth.tool - step))
    return np.column_stack(columns)


def joint_sensitivities(truth: Truth, q_reached: np.ndarray, eps: float = 1e-6) -> list[np.ndarray]:
    """Per joint, the derivative (N, 3) of each pose's measured point in that joint's angle."""
    out = []
    for j in range(q_reached.shape[1]):
        step = np.zeros_like(q_reached)
        step[:, j] = eps
        out.append((truth.points(q_reached + step) - truth.points(q_reached - step)) / (2 * eps))
    return out


def listed_columns(
    robot: Robot, truth: Truth, q_reached: np.ndarray, sens: list[np.ndarray]
) -> dict[tuple[str, str], np.ndarray]:
    """Columns (3N, k) of each listed effect on each joint, as the contract describes them."""
    tau = truth.gravity(q_reached)
    out: dict[tuple[str, str], np.ndarray] = {}
    for j, name in enumerate(robot.joints):
        qj = q_reached[:, j]
        mid = 0.5 * (robot.model.lowerPositionLimit[j] + robot.model.upperPositionLimit[j])
        shapes = {
            "joint_compliance": [tau[:, j]],
            "gear_harmonic1": [np.sin(qj), np.cos(qj)],
            "gear_harmonic2": [np.sin(2 * qj), np.cos(2 * qj)],
            "encoder_scale": [qj - mid],
            "backlash": [np.sign(tau[:, j])],
        }
        for effect, parts in shapes.items():
            out[(effect, name)] = np.column_stack([(sens[j] * s[:, None]).ravel() for s in parts])
    return out


def rest_rms(columns: np.ndarray, displacement: np.ndarray) -> float:
    """RMS norm (per pose) of the part of ``displacement`` orthogonal to the span of ``columns``."""
    y = displacement.ravel()
    scale = np.linalg.norm(columns, axis=0)
    scale[scale == 0] = 1.0
    coef, *_ = np.linalg.lstsq(columns / scale, y, rcond=1e-7)  # drop the redundant directions
    return rms_norm((y - (columns / scale) @ coef).reshape(-1, 3))


@dataclass
class Reference:
    """What an ideal calibrator leaves of an effect (metres, RMS norm per pose)."""

    rigid_rest: float
    listed_rest: float
    listed_best: str


def reference(robot: Robot, truth: Truth, q_reached: np.ndarray, effect: Effect) -> Reference:
    """The effect's rest after the best rigid fit, and after the best rigid fit plus one listed effect
    (or, for the pair, plus its two true listed effects)."""
    jac = rigid_jacobian(truth, q_reached)
    rigid = rest_rms(jac, effect.displacement)
    columns = listed_columns(robot, truth, q_reached, joint_sensitivities(truth, q_reached))
    if effect.listed:
        keys = [("gear_harmonic1" if e == "gear_harmonic" else e, j) for e, j in effect.listed]
        extra = np.column_stack([columns[k] for k in keys])
        return Reference(rigid, rest_rms(np.column_stack([jac, extra]), effect.displacement), "true pair")
    best, best_key = rigid, "none"
    for key, cols in columns.items():
        rest = rest_rms(np.column_stack([jac, cols]), effect.displacement)
        if rest < best:
            best, best_key = rest, f"{key[0]}:{key[1]}"
    return Reference(rigid, best, best_key)


# --------------------------------------------------------------------------------------------------
# Running pincal as an outside user
# --------------------------------------------------------------------------------------------------


def write_csv(path: Path, joints: list[str], q_cmd: np.ndarray, points: np.ndarray) -> None:
    """The measurement CSV of contracts.md: joint columns (rad), x,y,z (m)."""
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow([*joints, "x", "y", "z"])
        for qi, pi in zip(q_cmd, points):
            writer.writerow([f"{v:.10f}" for v in qi] + [f"{v:.9f}" for v in pi])


@dataclass
class Call:
    """One pincal run: its exit code, time, the JSON it wrote, and its last stderr line."""

    rc: int
    seconds: float
    payload: dict[str, Any] | None
    stderr: str


def _last(stderr: str, n: int = 3) -> str:
    """The last ``n`` non-empty lines of a stderr, joined by ' | '."""
    lines = [line.strip() for line in stderr.strip().splitlines() if line.strip()]
    return " | ".join(lines[-n:])


def run_pincal(args: list[str], out_json: Path, retry: bool = True) -> Call:
    """Run ``pincal ARGS`` (a subprocess, with a timeout) and read the JSON it wrote. A crash on an
    ImportError or SyntaxError (the source tree edited while the audit runs) is retried once."""
    env = dict(os.environ, PINCAL_THREADS=os.environ.get("PINCAL_THREADS", "1"))
    start = time.perf_counter()
    try:
        proc = subprocess.run(
            [*PINCAL, *args], capture_output=True, text=True, timeout=TIMEOUT_S, env=env, check=False
        )
        rc, stderr = proc.returncode, proc.stderr
    except subprocess.TimeoutExpired:
        rc, stderr = -9, f"timeout after {TIMEOUT_S:.0f} s"
    seconds = time.perf_counter() - start
    if rc == 1 and retry and ("ImportError" in stderr or "SyntaxError" in stderr):
        time.sleep(5.0)  # the source tree was mid-edit: one retry, and the table says so
        again = run_pincal(args, out_json, retry=False)
        return Call(again.rc, again.seconds, again.payload, f"retried after: {_last(stderr)}; {again.stderr}")
    payload = json.loads(out_json.read_text()) if rc == 0 and out_json.exists() else None
    return Call(rc, seconds, payload, _last(stderr))


def _harmonic(item: dict[str, Any]) -> int | None:
    """The order of a gear-harmonic cause: its ``harmonic`` key, else its ``JOINT.sinH`` parameter."""
    if item.get("harmonic"):
        return int(item["harmonic"])
    for name in item.get("parameters") or {}:
        tail = str(name).rsplit(".", 1)[-1]
        if tail.startswith("sin") and tail[3:].isdigit():
            return int(tail[3:])
    return None


def _cause_text(item: Any) -> str | None:
    """``effect[H]:joint`` of a cause object (None for none); H is the harmonic's order."""
    if isinstance(item, str):
        return None if item in ("", "none") else item
    if not isinstance(item, dict):
        return None
    effect = item.get("effect")
    if effect in (None, "none"):
        return None
    order = _harmonic(item) if effect == "gear_harmonic" else None
    joint = item.get("joint")
    name = f"{effect}{order or ''}"
    return f"{name}:{joint}" if joint else name


def calibrate_causes(report: dict[str, Any]) -> list[str]:
    """The causes calibrate kept: the report's ``extension`` (one object or a list), else its
    ``choice.cause``."""
    extension = report.get("extension")
    if extension:
        items = extension if isinstance(extension, list) else [extension]
        return [t for t in (_cause_text(i) for i in items) if t]
    choice = report.get("choice")
    cause = choice.get("cause") if isinstance(choice, dict) else None
    items = cause if isinstance(cause, list) else [cause]
    return [t for t in (_cause_text(i) for i in items) if t]


def diagnose_cause(diag: dict[str, Any]) -> str | None:
    """The cause diagnose named (None for none)."""
    return _cause_text(diag.get("cause"))


def implausible_named(payload: dict[str, Any], named: list[str], diagnosis: Any) -> list[str]:
    """Where a JSON flags a NAMED cause as implausible: the cause object itself, the diagnosis
    candidate of the same effect and joint, or the report's ``plausibility.plausible`` false."""
    found: list[str] = []
    plausibility = payload.get("plausibility")
    if isinstance(plausibility, dict) and plausibility.get("plausible") is False:
        found.append(f"plausibility: {plausibility.get('cause')} {plausibility.get('hint')}")
    extension = payload.get("extension")
    for item in extension if isinstance(extension, list) else [extension]:
        if isinstance(item, dict) and item.get("implausible"):
            found.append(f"extension {_cause_text(item)}: {str(item['implausible'])[:90]}")
    if isinstance(diagnosis, dict):
        for key in ("cause",):
            item = diagnosis.get(key)
            if isinstance(item, dict) and item.get("implausible"):
                found.append(f"cause {_cause_text(item)}: {str(item['implausible'])[:90]}")
        for item in diagnosis.get("candidates") or []:
            if isinstance(item, dict) and item.get("implausible") and _cause_text(item) in named:
                found.append(f"candidate {_cause_text(item)}: {str(item['implausible'])[:90]}")
    return found


# --------------------------------------------------------------------------------------------------
# One case, the table and the acceptance
# --------------------------------------------------------------------------------------------------


@dataclass
class Case:
    """One robot x effect x M x N x seed."""

    robot: str
    effect: str
    multiple: float
    n_poses: int
    seed: int


@dataclass
class Result:
    """What a case gave."""

    case: Case
    detail: str
    listed: list[tuple[str, str]]
    structure_mm: float
    rigid_rest_mm: float
    listed_rest_mm: float
    listed_best: str
    verdict: str | None = None
    unexplained_mm: float | None = None
    noise_mm: float | None = None
    noise_source: str | None = None
    rms_after_mm: float | None = None
    left_true_mm: float | None = None  # the final model against the noise-free truth, same poses
    cal_causes: list[str] = field(default_factory=list)
    diag_cause: str | None = None
    implausible: list[str] = field(default_factory=list)
    rc_cal: int = 0
    rc_diag: int = 0
    t_cal: float = 0.0
    t_diag: float = 0.0
    err_cal: str = ""
    err_diag: str = ""


def run_case(case: Case, robots: dict[str, Robot], sigma_mm: float, workdir: Path) -> Result:
    """Simulate one case, write its CSV, run calibrate and diagnose, and collect what they said."""
    robot = robots[case.robot]
    effect_index = EFFECTS.index(case.effect)
    rng = np.random.default_rng(
        [case.seed, case.n_poses, int(case.multiple * 10), effect_index, len(robot.joints)]
    )
    truth = Truth.draw(robot, rng)
    q_cmd = robot.sample(rng, case.n_poses)
    result, points, clean = simulate_effect(case, robot, truth, q_cmd + truth.offsets, rng, sigma_mm)
    return run_and_collect(result, robot, q_cmd, points, clean, sigma_mm, workdir)


def simulate_effect(
    case: Case,
    robot: Robot,
    truth: Truth,
    q_reached: np.ndarray,
    rng: np.random.Generator,
    sigma_mm: float,
) -> tuple[Result, np.ndarray, np.ndarray]:
    """Add the case's effect to a truth's measured points at the joint angles it reaches without the
    effect, ``q_reached`` (N, n, rad), and the noise (``sigma_mm`` per axis): the result to fill, with
    the effect's size and references [mm], the measured points and the noise-free ones (N, 3, m).

    ``truth`` is a :class:`Truth`, or a subclass with forward kinematics of its own.
    """
    target_m = case.multiple * np.sqrt(3.0) * sigma_mm * 1e-3
    effect, errors = make_effect(case.effect, robot, truth, q_reached, target_m, rng)
    points = truth.points(q_reached + errors)
    if not errors.any():  # a point displacement (bending, drift), not a joint error
        points = points + effect.displacement
    clean = points
    points = points + rng.normal(0.0, sigma_mm * 1e-3, points.shape)
    ref = (
        reference(robot, truth, q_reached, effect) if case.effect != "rigid" else Reference(0.0, 0.0, "none")
    )
    result = Result(
        case,
        effect.detail,
        effect.listed,
        rms_norm(effect.displacement) * 1e3,
        ref.rigid_rest * 1e3,
        ref.listed_rest * 1e3,
        ref.listed_best,
    )
    return result, points, clean


def run_and_collect(
    result: Result,
    robot: Robot,
    q_cmd: np.ndarray,
    points: np.ndarray,
    clean: np.ndarray,
    sigma_mm: float,
    workdir: Path,
) -> Result:
    """Write the measured points (N, 3, m) and the noise-free ones at commands ``q_cmd`` (rad), run
    calibrate (the noise-free poses as ``--test``, only scored) and diagnose with ``--noise sigma_mm``,
    and fill ``result`` with what they said."""
    case = result.case
    stem = f"{case.robot}_{case.effect}_M{case.multiple:g}_N{case.n_poses}_s{case.seed}"
    data = workdir / f"{stem}.csv"
    write_csv(data, robot.joints, q_cmd, points)
    truth_csv = workdir / f"{stem}.truth.csv"  # the same poses, noise-free: only scored, never fitted
    write_csv(truth_csv, robot.joints, q_cmd, clean)
    noise = f"{sigma_mm:g}"
    tip = ["--tip", robot.tip]
    report = workdir / f"{stem}.report.json"
    cal = run_pincal(
        ["calibrate", case.robot, str(data), *tip, "--noise", noise, "--test", str(truth_csv)]
        + ["--report", str(report)],
        report,
    )
    diag_json = workdir / f"{stem}.diagnose.json"
    diag = run_pincal(
        ["diagnose", case.robot, str(data), *tip, "--noise", noise, "--json", str(diag_json)], diag_json
    )
    result.rc_cal, result.t_cal, result.err_cal = cal.rc, cal.seconds, cal.stderr
    result.rc_diag, result.t_diag, result.err_diag = diag.rc, diag.seconds, diag.stderr
    if cal.payload is not None:
        residual = cal.payload.get("residual") or {}
        result.verdict = residual.get("verdict")
        result.unexplained_mm = residual.get("unexplained_mm")
        result.noise_mm = residual.get("noise_mm")
        result.noise_source = residual.get("noise_source")
        result.rms_after_mm = ((cal.payload.get("train") or {}).get("after") or {}).get("rms_mm")
        result.left_true_mm = ((cal.payload.get("test") or {}).get("after") or {}).get("rms_mm")
        result.cal_causes = calibrate_causes(cal.payload)
        diagnosis = (cal.payload.get("choice") or {}).get("diagnosis")
        flags = implausible_named(cal.payload, result.cal_causes, diagnosis)
        result.implausible += [f"calibrate {f}" for f in flags]
    if diag.payload is not None:
        result.diag_cause = diagnose_cause(diag.payload)
        named = [result.diag_cause] if result.diag_cause else []
        result.implausible += [f"diagnose {f}" for f in implausible_named({}, named, diag.payload)]
    return result


def _fmt(value: float | None, spec: str = ".3f") -> str:
    return "-" if value is None else format(value, spec)


def _short(cause: str | None) -> str:
    if not cause:
        return "none"
    return (
        cause.replace("joint_compliance", "compl")
        .replace("gear_harmonic", "harm")
        .replace("encoder_scale", "scale")
        .replace("_joint", "")
        .replace("panda_", "")
    )


def print_table(results: Iterable[Result]) -> None:
    """One line per case."""
    head = (
        f"{'robot':6} {'effect':8} {'M':>3} {'N':>4} {'s':>2} {'struct':>7} {'left':>7} {'listR':>7} "
        f"{'verdict':12} {'unexpl':>7} {'ratio':>6} {'rmsA':>6} {'calibrate':24} {'diagnose':20} "
        f"{'rc':5} {'t_cal':>6} {'t_dia':>6} impl"
    )
    print(head)
    print("-" * len(head))
    for r in results:
        c = r.case
        ratio = r.unexplained_mm / r.left_true_mm if r.unexplained_mm is not None and r.left_true_mm else None
        cal = ",".join(_short(x) for x in r.cal_causes) or "none"
        print(
            f"{c.robot:6} {c.effect:8} {c.multiple:>3g} {c.n_poses:>4} {c.seed:>2} {r.structure_mm:7.3f} "
            f"{_fmt(r.left_true_mm):>7} {r.listed_rest_mm:7.3f} {str(r.verdict):12} "
            f"{_fmt(r.unexplained_mm):>7} "
            f"{_fmt(ratio, '.2f'):>6} {_fmt(r.rms_after_mm):>6} {cal[:24]:24} {_short(r.diag_cause)[:20]:20} "
            f"{r.rc_cal},{r.rc_diag:<3} {r.t_cal:6.1f} {r.t_diag:6.1f} {len(r.implausible)}"
        )


def _pair_named(r: Result) -> bool:
    """Whether calibrate named both listed effects of the pair (order-1 harmonic, right joints)."""
    want = {f"gear_harmonic1:{r.listed[0][1]}", f"encoder_scale:{r.listed[1][1]}"}
    got = {c.replace("gear_harmonic:", "gear_harmonic1:") for c in r.cal_causes}
    return want <= got


def acceptance(results: list[Result]) -> list[tuple[str, int, int, list[str]]]:
    """(criterion, passed, total, failures) for each acceptance criterion."""
    out: list[tuple[str, int, int, list[str]]] = []

    def label(r: Result) -> str:
        c = r.case
        return f"{c.robot} {c.effect} M={c.multiple:g} N={c.n_poses} seed={c.seed}"

    rigid = [r for r in results if r.case.effect == "rigid"]
    fails = [
        f"{label(r)}: verdict {r.verdict}, unexplained {_fmt(r.unexplained_mm)}"
        for r in rigid
        if r.verdict != "explained"
    ]
    out.append(("1. rigid control -> explained", len(rigid) - len(fails), len(rigid), fails))

    outside = [r for r in results if r.case.effect in OUTSIDE and r.case.multiple >= 3]
    fails = []
    for r in outside:
        left = r.left_true_mm
        ok_ratio = r.unexplained_mm is not None and left is not None and left > 0
        ok_ratio = ok_ratio and 0.5 <= (r.unexplained_mm or 0.0) / (left or 1.0) <= 2.0
        if r.verdict != "unexplained" or not ok_ratio:
            fails.append(
                f"{label(r)}: verdict {r.verdict}, unexplained {_fmt(r.unexplained_mm)} mm vs left "
                f"{_fmt(left)} mm (structure {r.structure_mm:.3f}, rigid rest {r.rigid_rest_mm:.3f}, listed "
                f"rest {r.listed_rest_mm:.3f} [{r.listed_best}]), calibrate named {r.cal_causes or 'none'}"
            )
    out.append(
        (
            "2. outside effect -> unexplained, unexplained_mm within x2 of what the final model leaves",
            len(outside) - len(fails),
            len(outside),
            fails,
        )
    )

    pairs = [r for r in results if r.case.effect == "pair"]
    fails = [
        f"{label(r)}: verdict {r.verdict}, calibrate named {r.cal_causes or 'none'}, diagnose {r.diag_cause}"
        for r in pairs
        if not (_pair_named(r) or r.verdict == "unexplained")
    ]
    out.append(
        ("3. two listed effects -> both named or unexplained", len(pairs) - len(fails), len(pairs), fails)
    )

    fails = []
    both = [r for r in results if r.rc_cal == 0 and r.rc_diag == 0]
    for r in both:
        if not _agree(r):
            fails.append(f"{label(r)}: calibrate {r.cal_causes or 'none'}, diagnose {r.diag_cause or 'none'}")
    skipped = len(results) - len(both)
    name = f"4. calibrate and diagnose name the same cause (runs where both exit 0; {skipped} not)"
    out.append((name, len(both) - len(fails), len(both), fails))

    fails = [
        f"{label(r)}: calibrate rc {r.rc_cal} [{r.err_cal}], diagnose rc {r.rc_diag} [{r.err_diag}]"
        for r in results
        if r.rc_cal != 0 or r.rc_diag != 0
    ]
    out.append(("5. no run exits non-zero", len(results) - len(fails), len(results), fails))
    return out


def _agree(r: Result) -> bool:
    """Whether calibrate's first cause is the one diagnose named (or both named none)."""
    return (r.cal_causes[0] if r.cal_causes else None) == r.diag_cause


def _by_robot_and_effect(results: Iterable[Result]) -> dict[tuple[str, str], list[Result]]:
    """The results grouped by robot and effect, in the order met."""
    groups: dict[tuple[str, str], list[Result]] = {}
    for r in results:
        groups.setdefault((r.case.robot, r.case.effect), []).append(r)
    return groups


def print_ratios(results: list[Result]) -> None:
    """Per robot and effect, the range of unexplained_mm over the true structure RMS, over what a rigid
    model cannot absorb (rigidR) and over what rigid + the best single listed effect cannot (listR)."""
    groups = _by_robot_and_effect(
        r for r in results if r.case.effect != "rigid" and r.unexplained_mm is not None
    )
    print("unexplained_mm / reference, min-max over M, N, seeds (information):")
    for (robot, effect), rs in sorted(groups.items()):
        parts = []
        for label, ref in (
            ("left", "left_true_mm"),
            ("struct", "structure_mm"),
            ("rigidR", "rigid_rest_mm"),
            ("listR", "listed_rest_mm"),
        ):
            values = [
                r.unexplained_mm / getattr(r, ref)
                for r in rs
                if (getattr(r, ref) or 0.0) > 0.01 and r.unexplained_mm
            ]
            if values:
                parts.append(f"{label} {min(values):.2f}-{max(values):.2f}")
        named = sorted({c for r in rs for c in (r.cal_causes or ["none"])})
        print(f"    {robot:6} {effect:8} {'  '.join(parts):44} calibrate named: {', '.join(named)}")


def summary_rows(results: list[Result]) -> list[list[object]]:
    """Per robot and effect: the runs, their verdicts, the causes calibrate named (how often each
    set), whether diagnose named the same first cause, and unexplained_mm over what the final
    model truly leaves (min-max)."""
    groups = _by_robot_and_effect(results)
    rows: list[list[object]] = []
    for (robot, effect), rs in sorted(groups.items(), key=lambda g: (g[0][0], EFFECTS.index(g[0][1]))):
        verdicts = Counter(str(r.verdict) for r in rs)
        named = Counter(", ".join(_short(c) for c in r.cal_causes) or "none" for r in rs)
        same = sum(1 for r in rs if _agree(r))
        ratios = [
            r.unexplained_mm / r.left_true_mm
            for r in rs
            if r.unexplained_mm and r.left_true_mm is not None and r.left_true_mm > 0
        ]
        rows.append(
            [
                robot,
                effect,
                len(rs),
                ", ".join(f"`{v}` {k}/{len(rs)}" for v, k in verdicts.most_common()),
                "; ".join(f"{k} × {v}" for v, k in named.most_common()),
                f"{same}/{len(rs)}",
                f"{min(ratios):.2f}-{max(ratios):.2f}" if ratios else "-",
            ]
        )
    return rows


def write_markdown(path: Path, argv: list[str] | None, results: list[Result], script: str) -> None:
    """The page of the run: the summary per robot and effect and the acceptance criteria. Its
    writer (``markdown_page``) imports pincal for its version; the simulation above does not."""
    from markdown_page import command_line, table, write_page

    header = ["robot", "effect", "runs", "verdict", "calibrate named", "diagnose agrees", "unexpl. / left"]
    criteria = [f"- {'PASS' if p == t else 'FAIL'} {name}: {p}/{t}" for name, p, t, _ in acceptance(results)]
    note = (
        "`unexpl. / left`: the verdict's `unexplained_mm` over what the final model truly leaves above "
        "the noise (its error against the noise-free truth on the same poses, given as `--test`); "
        "causes: `harm` a gear harmonic, `compl` a joint compliance, `scale` an encoder scale, "
        "`lost_motion` a lost motion, each with its joint."
    )
    command = command_line(script, sys.argv[1:] if argv is None else argv, {})
    write_page(path, command, [table(header, summary_rows(results)), "", note, "", *criteria])


def build_cases(
    robots: list[str], poses: list[int], multiples: list[float], seeds: int, first_seed: int = 0
) -> list[Case]:
    """Every robot x effect x M x N x seed (the rigid control once per robot x N x seed)."""
    cases = []
    for seed in range(first_seed, first_seed + seeds):
        for robot in robots:
            for n in poses:
                cases.append(Case(robot, "rigid", 0, n, seed))
                for effect in EFFECTS[1:]:
                    cases.extend(Case(robot, effect, m, n, seed) for m in multiples)
    return cases


Runner = Callable[[Case, dict[str, Robot], float, Path], Result]


def parse_args(argv: list[str] | None, doc: str | None) -> argparse.Namespace:
    """The audit's options (``--quick`` applied; ``--sigma`` in mm per axis); sets the pincal command.

    Args:
        argv: the command line (default ``sys.argv[1:]``).
        doc: the module docstring whose first paragraph is the ``--help`` description.
    """
    parser = argparse.ArgumentParser(description=(doc or "").split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="ur5, N=60, M in {3, 10}, one seed")
    parser.add_argument("--robots", nargs="+", choices=sorted(SPECS), default=["ur5", "panda"])
    parser.add_argument("--poses", nargs="+", type=int, default=[60, 100])
    parser.add_argument("--multiples", nargs="+", type=float, default=[3, 6, 10])
    parser.add_argument("--effects", nargs="+", choices=EFFECTS, default=list(EFFECTS))
    parser.add_argument("--seeds", type=int, default=1, help="number of seeds")
    parser.add_argument("--first-seed", type=int, default=0, help="the first seed")
    parser.add_argument("--sigma", type=float, default=0.05, help="noise per axis [mm]")
    parser.add_argument("--jobs", type=int, default=1, help="cases run at once")
    parser.add_argument("--json", type=Path, help="write every result here")
    parser.add_argument("--keep", type=Path, help="keep the CSVs and JSONs in this folder")
    parser.add_argument("--markdown", type=Path, help="also write the summary and acceptance in Markdown")
    parser.add_argument(
        "--pincal",
        default="pincal",
        help="the pincal command (default 'pincal'; e.g. 'python -m pincal' with PYTHONPATH on a snapshot)",
    )
    args = parser.parse_args(argv)
    PINCAL[:] = shlex.split(args.pincal)
    if args.quick:
        args.robots, args.poses, args.multiples, args.seeds = ["ur5"], [60], [3.0, 10.0], 1
    return args


def main(
    argv: list[str] | None = None,
    run: Runner = run_case,
    load: Callable[[RobotSpec], Robot] = Robot.load,
    doc: str | None = __doc__,
) -> int:
    """Run the audit; exit status 1 when an acceptance criterion fails.

    Args:
        argv: the command line (default ``sys.argv[1:]``).
        run: simulates and runs one case (``sigma`` in mm per axis, files written in the folder).
        load: the robot of a spec, as ``run`` takes it.
        doc: the module docstring whose first paragraph is the ``--help`` description.
    """
    args = parse_args(argv, doc)
    robots = {name: load(SPECS[name]) for name in args.robots}
    cases = [
        c
        for c in build_cases(args.robots, args.poses, args.multiples, args.seeds, args.first_seed)
        if c.effect in args.effects
    ]
    print(
        f"{len(cases)} cases, sigma {args.sigma} mm (floor {np.sqrt(3) * args.sigma:.4f} mm), "
        f"tips {', '.join(f'{r.spec.name}:{r.tip}' for r in robots.values())}",
        flush=True,
    )

    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="verdict_audit_") as tmp:
        workdir = args.keep or Path(tmp)
        workdir.mkdir(parents=True, exist_ok=True)
        job: Callable[[Case], Result] = lambda c: run(c, robots, args.sigma, workdir)  # noqa: E731
        results: list[Result] = []
        with ThreadPoolExecutor(max_workers=max(1, args.jobs)) as pool:
            for i, r in enumerate(pool.map(job, cases), 1):
                results.append(r)
                c = r.case
                print(
                    f"[{i}/{len(cases)} {time.perf_counter() - start:5.0f} s] {c.robot} {c.effect} "
                    f"M={c.multiple:g} N={c.n_poses} seed={c.seed}: {r.verdict} "
                    f"{_fmt(r.unexplained_mm)} / {r.structure_mm:.3f} mm, calibrate "
                    f"{r.cal_causes or 'none'}, diagnose {r.diag_cause}, rc {r.rc_cal},{r.rc_diag}",
                    flush=True,
                )
    print()
    print_table(results)
    print()
    print(
        f"total {time.perf_counter() - start:.0f} s; structure = true RMS of the effect [mm]; "
        "rigidR / listR = what a rigid model / rigid + best listed effect cannot absorb (linearised); "
        "ratio = unexpl / struct"
    )
    print_ratios(results)
    failed = False
    for name, passed, total, fails in acceptance(results):
        status = "PASS" if passed == total else "FAIL"
        failed |= passed != total
        print(f"{status} {name}: {passed}/{total}")
        for f in fails:
            print(f"    {f}")
    flagged = [r for r in results if r.implausible]
    if flagged:
        print("implausible flags:")
        for r in flagged:
            print(
                f"    {r.case.robot} {r.case.effect} M={r.case.multiple:g} N={r.case.n_poses} "
                f"seed={r.case.seed}: {r.implausible}"
            )
    if args.json:
        args.json.write_text(json.dumps([asdict(r) for r in results], indent=1))
    if args.markdown:
        write_markdown(args.markdown, argv, results, Path(sys.argv[0]).name)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
