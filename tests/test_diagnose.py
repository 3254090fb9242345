"""Tests of ``pincal diagnose`` and of models extended by a non-geometric effect.

- Hidden effects: a simulated robot (random geometric errors, unknown instrument frame and tool
  point) with one effect hidden at 0.3-0.8 mm RMS at the tip, 80 poses, 0.03 mm noise:
  :func:`pincal.auto.diagnose.diagnose` names the effect and the joint, with a cross-validated gain of
  at least 3 and an extended cross-validated RMS within 1.5x the noise floor ``0.03 sqrt(3)`` mm.
- No false causes: on 20 seeded datasets with nothing hidden, ``diagnose`` answers ``none`` in at
  least 19.
- The command line: ``pincal diagnose --json --plots`` writes the JSON of ``contracts.md`` and a
  PNG; ``pincal calibrate --extend`` predicts held-out poses to the noise floor and recovers the
  hidden effect's parameters; bad ``--extend`` and ``--plots`` values exit 2 with one error line.
- The extension's analytic Jacobian matches central finite differences.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import pincal
import pincal.auto.diagnose
import pincal.identify.measurement
import pincal.kinematics.effects
import pincal.kinematics.mdh
from pincal.auto.diagnose import Diagnosis, diagnose
from pincal.cli import main
from pincal.kinematics.effects import EFFECTS, Extension, candidates
from pincal.simulation.truth import TrueRobot, hide_effect

NOISE = 3e-5  # 1σ of each measured coordinate [m]
NOISE_FLOOR_MM = NOISE * 1e3 * np.sqrt(3.0)  # RMS of a 3-D noise vector [mm], 0.052 mm
N_POSES = 80
MIN_GAIN = 3.0
MAX_EXTENDED_MM = 1.5 * NOISE_FLOOR_MM
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
FD_STEP = 1e-6
FD_RTOL = 1e-6


def hidden_effect_data(
    robot: pincal.Robot, label: str, rms: float, seed: int, n_poses: int = N_POSES
) -> tuple[TrueRobot, pincal.Dataset]:
    """A seeded truth with the effect ``label`` hidden at ``rms`` [m] at the tip, and its data.

    Args:
        robot: the nominal robot.
        label: ``EFFECT:JOINT`` as :meth:`pincal.kinematics.effects.Extension.parse` reads it.
        rms: RMS of the effect's tip displacement over the poses [m].
        seed: seed of the geometric errors, instrument, tool, poses, effect and noise.
        n_poses: number of poses.

    Returns:
        The truth (its ``effect`` holds the hidden parameters) and the measured positions.
    """
    truth, fit, _ = pincal.simulate(robot, n_fit=n_poses, n_test=1, seed=seed)
    ext = Extension.parse(robot, label)
    truth = hide_effect(truth, ext, fit.q, rms, seed=seed)
    return truth, truth.measure(fit.q, noise=NOISE, rot_noise=None, seed=seed + 1000)


def describe(d: Diagnosis, top: int = 3) -> str:
    """The answer of a diagnosis and its best candidates, for assertion messages."""
    answer = d.cause.extension.label if d.cause else "none"
    best = ", ".join(
        f"{c.extension.label} cv={c.cv_rms_mm:.4f} mm p={c.p_value:.2g}" for c in d.candidates[:top]
    )
    return (
        f"answer {answer}, baseline cv={d.baseline_cv_rms_mm:.4f} mm, gain={d.gain:.2f}; "
        f"best candidates: {best}"
    )


def run_cli(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    """``pincal.cli.main(argv)``: exit code, stdout and stderr."""
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def assert_one_error_line(code: int, err: str) -> None:
    """Exit code 2 and exactly one ``pincal: error:`` line on stderr."""
    lines = err.strip().splitlines()
    assert code == 2, err
    assert len(lines) == 1, err
    assert lines[0].startswith("pincal: error:"), err


# --- hidden effects are named ---------------------------------------------------------------------

#: (robot, EFFECT:JOINT, seed, RMS of the effect at the tip [m]). Compliance and backlash sit on
#: joints that carry gravity torque (not the vertical first joint).
HIDDEN_CASES = [
    ("ur5", "joint_compliance:shoulder_lift_joint", 101, 0.50e-3),
    ("ur5", "joint_compliance:elbow_joint", 102, 0.35e-3),
    ("panda", "joint_compliance:panda_joint2", 103, 0.70e-3),
    ("panda", "joint_compliance:panda_joint4", 104, 0.45e-3),
    ("ur5", "gear_harmonic:elbow_joint", 105, 0.60e-3),
    ("ur5", "gear_harmonic:wrist_1_joint", 106, 0.30e-3),
    ("panda", "gear_harmonic:panda_joint3", 107, 0.80e-3),
    ("panda", "gear_harmonic:panda_joint5", 108, 0.40e-3),
    ("ur5", "encoder_scale:shoulder_pan_joint", 109, 0.55e-3),
    ("ur5", "encoder_scale:wrist_1_joint", 110, 0.75e-3),
    ("panda", "encoder_scale:panda_joint1", 111, 0.30e-3),
    ("panda", "encoder_scale:panda_joint6", 112, 0.65e-3),
    ("ur5", "backlash:shoulder_lift_joint", 113, 0.65e-3),
    ("ur5", "backlash:elbow_joint", 114, 0.30e-3),
    ("panda", "backlash:panda_joint2", 115, 0.50e-3),
    ("panda", "backlash:panda_joint4", 116, 0.75e-3),
    ("ur5", "gear_harmonic2:wrist_2_joint", 117, 0.45e-3),
    ("ur5", "lost_motion:shoulder_lift_joint", 118, 0.40e-3),
    ("ur5", "lost_motion:wrist_2_joint", 119, 0.55e-3),
    ("panda", "lost_motion:panda_joint2", 120, 0.45e-3),
    ("panda", "lost_motion:panda_joint6", 121, 0.35e-3),
]


def test_hidden_cases_cover_every_effect_on_two_robots_and_two_joints() -> None:
    """Every effect of :data:`pincal.kinematics.effects.EFFECTS` is hidden on two joints of ur5 and panda."""
    covered: dict[tuple[str, str], set[str]] = {}
    for name, label, _, rms in HIDDEN_CASES:
        effect, _, joint = label.partition(":")
        covered.setdefault((name, effect), set()).add(joint)
        assert 0.3e-3 <= rms <= 0.8e-3
    for effect in EFFECTS:
        for name in ("ur5", "panda"):
            assert len(covered.get((name, effect), set())) == 2, (name, effect)
    assert ("ur5", "gear_harmonic2") in covered


@pytest.mark.parametrize(
    ("name", "label", "seed", "rms"),
    HIDDEN_CASES,
    ids=[f"{c[0]}-{c[1]}" for c in HIDDEN_CASES],
)
def test_diagnose_names_hidden_effect(get_robot, name: str, label: str, seed: int, rms: float) -> None:
    """The hidden effect and joint are named, with a gain >= 3 down to the noise floor."""
    robot = get_robot(name)
    truth, data = hidden_effect_data(robot, label, rms, seed)
    hidden = truth.extension
    assert hidden is not None
    d = diagnose(robot, data)
    message = f"{name} seed {seed}, hidden {label} at {rms * 1e3:.2f} mm: {describe(d)}"
    assert d.cause is not None, message
    assert d.cause.extension.effect == hidden.effect, message
    assert d.cause.extension.joint == hidden.joint, message
    assert d.cause.extension.harmonic == hidden.harmonic, message
    assert d.gain >= MIN_GAIN, message
    assert d.extended_cv_rms_mm <= MAX_EXTENDED_MM, message
    cause = d.to_dict()["cause"]
    assert (cause["effect"], cause["joint"]) == (hidden.effect, hidden.joint), message


# --- nothing hidden: no false causes --------------------------------------------------------------

NULL_DATASETS = [("ur5", s) for s in range(200, 210)] + [("panda", s) for s in range(300, 310)]


def test_diagnose_names_no_cause_without_hidden_effect(get_robot) -> None:
    """On 20 datasets with only geometric errors and noise, ``none`` in at least 19."""
    answers = []
    n_none = 0
    for name, seed in NULL_DATASETS:
        robot = get_robot(name)
        _, data, _ = pincal.simulate(robot, n_fit=N_POSES, n_test=1, seed=seed, noise=NOISE)
        d = diagnose(robot, data)
        cause = d.to_dict()["cause"]
        is_none = d.cause is None and cause["effect"] == "none" and cause["joint"] is None
        n_none += is_none
        answers.append(f"{name} seed {seed}: {describe(d, top=2)}")
    assert len(answers) == 20
    assert n_none >= 19, f"{n_none}/20 answered none:\n" + "\n".join(answers)


# --- the command line -----------------------------------------------------------------------------


def test_cli_diagnose_json_and_plot(get_robot, tmp_path: Path, capsys) -> None:
    """``pincal diagnose --json --plots``: the JSON of ``contracts.md`` and a PNG of the cause."""
    robot = get_robot("ur5")
    truth, data = hidden_effect_data(robot, "backlash:elbow_joint", 0.55e-3, seed=121)
    csv = tmp_path / "data.csv"
    pincal.write_csv(csv, data)
    plots = tmp_path / "plots"
    plots.mkdir()
    out = tmp_path / "diagnosis.json"
    code, stdout, err = run_cli(capsys, "diagnose", "ur5", csv, "--json", out, "--plots", plots)
    assert code == 0, err
    result = json.loads(out.read_text())

    assert isinstance(result["baseline"]["model"], str)
    assert result["baseline"]["model"] == "placements"
    baseline = result["baseline"]["cv_rms_mm"]
    extended = result["extended"]["cv_rms_mm"]
    assert isinstance(baseline, float) and isinstance(extended, float)
    assert abs(result["gain"] - baseline / extended) <= 1e-9
    cause = result["cause"]
    assert (cause["effect"], cause["joint"]) == ("backlash", "elbow_joint"), stdout
    judged = result["candidates"]
    assert len(judged) == len(candidates(robot))
    for cand in judged:
        assert cand["effect"] in EFFECTS
        assert cand["joint"] in robot.joint_names
        assert isinstance(cand["cv_rms_mm"], float) and cand["cv_rms_mm"] > 0.0
    cv = [c["cv_rms_mm"] for c in judged]
    assert cv == sorted(cv)
    assert (judged[0]["effect"], judged[0]["joint"]) == ("backlash", "elbow_joint")
    assert extended == judged[0]["cv_rms_mm"]

    pngs = sorted(plots.glob("*.png"))
    assert len(pngs) == 1, stdout
    assert pngs[0].read_bytes()[:8] == PNG_SIGNATURE


def test_cli_diagnose_missing_plots_folder(get_robot, tmp_path: Path, capsys) -> None:
    """A ``--plots`` folder that does not exist is created (it used to be refused), and holds the
    one PNG; ``--plot FILE.png`` writes the same figure there, as ``accuracy --plot`` does."""
    robot = get_robot("ur5")
    _, data, _ = pincal.simulate(robot, n_fit=20, n_test=1, seed=3)
    csv = tmp_path / "data.csv"
    pincal.write_csv(csv, data)
    out = tmp_path / "diagnosis.json"
    folder = tmp_path / "no_such_folder" / "figures"
    code, _, err = run_cli(
        capsys, "diagnose", "ur5", csv, "--json", out, "--plots", folder, "--params", "all"
    )
    assert code == 0, err
    pngs = list(folder.glob("*.png"))
    assert len(pngs) == 1 and pngs[0].read_bytes()[:8] == PNG_SIGNATURE
    one = tmp_path / "cause.png"
    code, _, err = run_cli(capsys, "diagnose", "ur5", csv, "--plot", one, "--params", "all")
    assert code == 0, err
    assert one.read_bytes() == pngs[0].read_bytes()
    code, _, err = run_cli(capsys, "diagnose", "ur5", csv, "--plots", one, "--params", "all", "--force")
    assert_one_error_line(code, err)


#: (EFFECT:JOINT, seed, RMS at the tip [m]) hidden in ur5 data for ``calibrate --extend``.
EXTEND_CASES = [
    ("joint_compliance:shoulder_lift_joint", 141, 0.50e-3),
    ("gear_harmonic:elbow_joint", 142, 0.40e-3),
    ("gear_harmonic2:wrist_2_joint", 143, 0.35e-3),
    ("encoder_scale:wrist_1_joint", 144, 0.70e-3),
    ("backlash:elbow_joint", 145, 0.60e-3),
]


@pytest.mark.parametrize(("label", "seed", "rms"), EXTEND_CASES, ids=[c[0] for c in EXTEND_CASES])
def test_cli_calibrate_extend(get_robot, tmp_path: Path, capsys, label: str, seed: int, rms: float) -> None:
    """``calibrate --extend --geometry joint`` predicts held-out poses to the noise floor and finds
    the effect (the default, geometry first, is tested in ``test_delivery.py``).

    200 poses, a quarter of them held out: the held-out RMS is within 1.2x the noise floor, the
    report lists the effect's parameters, and the sidecar holds the effect with parameters within
    10 % of the hidden ones.
    """
    robot = get_robot("ur5")
    truth, data = hidden_effect_data(robot, label, rms, seed, n_poses=200)
    hidden = truth.extension
    assert hidden is not None and truth.effect is not None
    csv = tmp_path / "data.csv"
    pincal.write_csv(csv, data)
    urdf, report = tmp_path / "out.urdf", tmp_path / "report.json"
    args = ["calibrate", "ur5", csv, "--extend", label, "--geometry", "joint", "--holdout", "0.25"]
    args += ["-o", urdf]
    code, _, err = run_cli(capsys, *args, "--report", report)
    assert code == 0, err
    rep = json.loads(report.read_text())
    held_out = rep["test"]["after"]["rms_mm"]
    assert held_out <= 1.2 * NOISE_FLOOR_MM, f"held-out RMS {held_out:.4f} mm"
    names = {p["name"] for p in rep["parameters"]}
    assert set(hidden.names) <= names, sorted(names)
    if hidden.effect == "joint_compliance":
        assert f"{hidden.joint}.compliance" in names

    side = json.loads((tmp_path / "out.calibration.json").read_text())
    ext = side["extension"]
    assert ext is not None
    assert (ext["effect"], ext["joint"]) == (hidden.effect, hidden.joint)
    if hidden.effect == "gear_harmonic":
        assert ext["harmonic"] == hidden.harmonic
    assert list(ext["parameters"]) == list(hidden.names)
    values = np.array([ext["parameters"][n]["value"] for n in hidden.names])
    error = np.linalg.norm(values - truth.effect) / np.linalg.norm(truth.effect)
    assert error < 0.10, f"identified {values}, hidden {truth.effect}"


@pytest.mark.parametrize("extend", ["bogus:joint", "joint_compliance:no_such_joint"])
def test_cli_calibrate_bad_extend(get_robot, tmp_path: Path, capsys, extend: str) -> None:
    """An unknown effect or joint in ``--extend``: exit 2 with one error line, nothing written."""
    robot = get_robot("ur5")
    _, data, _ = pincal.simulate(robot, n_fit=30, n_test=1, seed=4)
    csv = tmp_path / "data.csv"
    pincal.write_csv(csv, data)
    urdf, report = tmp_path / "out.urdf", tmp_path / "report.json"
    code, _, err = run_cli(
        capsys, "calibrate", "ur5", csv, "--extend", extend, "-o", urdf, "--report", report
    )
    assert_one_error_line(code, err)
    assert not urdf.exists() and not report.exists()


# --- the extension's Jacobian ---------------------------------------------------------------------

JACOBIAN_EXTENSIONS = {
    "ur5": [
        "joint_compliance:shoulder_lift_joint",
        "gear_harmonic:elbow_joint",
        "gear_harmonic2:wrist_1_joint",
        "encoder_scale:wrist_2_joint",
        "backlash:elbow_joint",
    ],
    "panda": [
        "joint_compliance:panda_joint4",
        "gear_harmonic:panda_joint3",
        "gear_harmonic2:panda_joint6",
        "encoder_scale:panda_joint1",
        "backlash:panda_joint2",
    ],
}
JACOBIAN_CASES = [(name, label) for name, labels in JACOBIAN_EXTENSIONS.items() for label in labels]


def relative_error(jac: np.ndarray, jac_fd: np.ndarray) -> float:
    """``max |J - J_fd| / max |J|``."""
    scale = float(np.max(np.abs(jac)))
    assert scale > 0.0
    return float(np.max(np.abs(jac - jac_fd)) / scale)


@pytest.mark.parametrize("kind", ["placements", "mdh"])
@pytest.mark.parametrize(("name", "label"), JACOBIAN_CASES)
def test_extension_jacobian_matches_finite_differences(get_robot, name: str, label: str, kind: str) -> None:
    """Position residuals with a random registration, tool and effect: analytic = central FD.

    The effect's parameters are drawn so that the joint error is about 0.01 rad (or m); each
    column's finite-difference step moves its joint (or parameter) by about 1e-6.
    """
    robot = get_robot(name)
    rng = np.random.default_rng(17)
    pin.seed(17)  # SE3.Random draws from Eigen's generator
    ext = Extension.parse(robot, label)
    model = pincal.kinematics.mdh.make_model(kind, robot)
    measurement = pincal.identify.measurement.Measurement(
        "position", instrument_T_base=pin.SE3.Random(), tool=pin.SE3.Random()
    )
    q = robot.random_configurations(12, rng)
    placeholder = pincal.Dataset(robot.joint_names, q, np.zeros((len(q), 3)))
    draft = pincal.identify.measurements.Problem(model, measurement, placeholder, ext)
    assert draft.names[model.n_params : draft.n_model] == ext.names
    regressor_rms = np.sqrt(np.mean(draft.regressors**2, axis=0))
    assert np.all(regressor_rms > 0.0)
    theta = draft.initial_theta() + rng.normal(0.0, 0.01, draft.n_params)
    effect = slice(model.n_params, draft.n_model)
    theta[effect] = rng.normal(0.0, 0.01, ext.n_params) / regressor_rms
    points = draft.predict(theta)[0] + rng.normal(0.0, 1e-3, (len(q), 3))
    problem = pincal.identify.measurements.Problem(
        model, measurement, pincal.Dataset(robot.joint_names, q, points), ext
    )

    jac = problem.jacobian(theta)
    assert jac.shape == (3 * len(q), problem.n_params)
    steps = np.full(problem.n_params, FD_STEP)
    steps[effect] = FD_STEP / regressor_rms
    jac_fd = np.empty_like(jac)
    for c in range(problem.n_params):
        step = np.zeros(problem.n_params)
        step[c] = steps[c]
        plus, minus = problem.residuals(theta + step), problem.residuals(theta - step)
        jac_fd[:, c] = (plus - minus) / (2 * steps[c])
    assert relative_error(jac, jac_fd) <= FD_RTOL
    # The effect's columns on their own scale (compliance columns are in m per rad/(N·m)).
    assert relative_error(jac[:, effect], jac_fd[:, effect]) <= FD_RTOL
    # They are the joint's column times the regressor: moving p moves the joint by r(q) p.
    q_moved = problem.reached(theta)
    assert np.allclose(q_moved - q, ext.joint_error(q, theta[effect]), atol=1e-15)
