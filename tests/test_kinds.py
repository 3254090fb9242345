"""The measurement kinds (:mod:`pincal.identify.kinds`): the registry, and each kind's residual rows.

- ``KINDS`` holds one kind per ``--measure`` name, and :func:`pincal.identify.kinds.get_kind` refuses an
  unknown name with a :class:`pincal.DataError` that lists the names.
- For every kind, :meth:`MeasurementKind.rows` on a problem of 6 random UR5 poses (random
  registration and tool, θ near the nominal) gives as many rows as the kind says, and its Jacobian
  matches central finite differences of its residuals (relative error <= 1e-6); some columns
  asked for alone equal those columns of the whole Jacobian.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import pincal
import pincal.identify.kinds
import pincal.identify.measurement
import pincal.kinematics.mdh
from pincal.identify.kinds import KINDS, MeasurementKind, get_kind
from pincal.options import MEASURES

N_POSES = 6
FD_RTOL = 1e-6  # max |J - J_fd| / max |J|
FD_STEP = 1e-6


def make_problem(
    robot: pincal.Robot, measure: str, seed: int
) -> tuple[pincal.identify.measurements.Problem, np.ndarray]:
    """A ``placements`` problem of ``measure`` on random poses, its data the model's own
    predictions at a random θ, slightly perturbed; fixed points: two points, three rows each, and
    one known distance between them."""
    rng = np.random.default_rng(seed)
    pin.seed(seed)
    model = pincal.kinematics.mdh.make_model("placements", robot)
    q = robot.random_configurations(N_POSES, rng)
    labels = np.repeat([0, 1], N_POSES // 2)
    names = ("a", "b") if measure == "points" else ()
    measurement = pincal.identify.measurement.Measurement(
        measure,
        instrument_T_base=pin.SE3.Random(),
        tool=pin.SE3.Random(),
        points=names,
        point_distances=(("a", "b", 0.3),) if names else (),
    )
    quats = np.tile([1.0, 0.0, 0.0, 0.0], (N_POSES, 1))

    def dataset(points: np.ndarray) -> pincal.Dataset:
        return pincal.Dataset(robot.joint_names, q, points, quats, labels=labels, point_names=names)

    draft = pincal.identify.measurements.Problem(model, measurement, dataset(np.zeros((N_POSES, 3))))
    theta = draft.initial_theta() + rng.normal(0.0, 0.01, draft.n_params)
    points, rotations = draft.predict(theta)
    points = points + rng.normal(0.0, 1e-3, points.shape)
    for i, r in enumerate(rotations):
        qt = pin.Quaternion(pin.exp3(rng.normal(0.0, 0.02, 3)) @ r)
        quats[i] = (qt.w, qt.x, qt.y, qt.z)
    return pincal.identify.measurements.Problem(model, measurement, dataset(points)), theta


def test_registry_holds_every_measure() -> None:
    assert tuple(KINDS) == MEASURES
    for name, kind in KINDS.items():
        assert isinstance(kind, MeasurementKind) and kind.name == name and get_kind(name) is kind
        assert pincal.identify.measurement.Measurement(name).measure is kind
        assert kind.tool_dof in (3, 6)


@pytest.mark.parametrize("name", ["laser", "", "Position"])
def test_unknown_kind_is_refused_with_the_names(name: str) -> None:
    with pytest.raises(pincal.DataError, match="unknown measure") as raised:
        get_kind(name)
    assert all(k in str(raised.value) for k in KINDS)
    with pytest.raises(pincal.DataError, match="position, pose, distance, points"):
        pincal.identify.measurement.Measurement(name)


def test_unknowns_follow_the_kind() -> None:
    """Registration: position and pose only; tool: 6 for pose, else 3; points: fixed points."""
    for name, kind in KINDS.items():
        m = pincal.identify.measurement.Measurement(name, points=("a",) if kind.fixed_points else ())
        assert m.n_instrument == (6 if kind.registered else 0)
        assert m.n_tool == kind.tool_dof
        assert m.n_points == (3 if kind.fixed_points else 0)
        assert pincal.identify.measurement.Measurement(name, fit_tool=False, fit_instrument=False).n_tool == 0


@pytest.mark.parametrize("measure", MEASURES)
def test_rows_jacobian_matches_finite_differences(get_robot, measure: str) -> None:
    problem, theta = make_problem(get_robot("ur5"), measure, seed=3)
    kind = problem.measurement.measure
    cols = np.arange(problem.n_params)
    res, jac = kind.rows(problem, theta, cols)
    n_rows = N_POSES * (N_POSES - 1) // 2 if kind.by_pairs else kind.width * N_POSES
    assert len(res) == n_rows + (1 if kind.fixed_points else 0) == len(kind.owners(problem))
    assert problem.n_rows() == len(res)  # counted without computing them
    assert np.array_equal(res, kind.rows(problem, theta, None)[0])
    assert jac.shape == (len(res), problem.n_params)
    jac_fd = np.empty_like(jac)
    for c in cols:
        step = np.zeros(problem.n_params)
        step[c] = FD_STEP
        plus, minus = kind.rows(problem, theta + step, None)[0], kind.rows(problem, theta - step, None)[0]
        jac_fd[:, c] = (plus - minus) / (2 * FD_STEP)
    assert np.max(np.abs(jac - jac_fd)) / np.max(np.abs(jac)) <= FD_RTOL
    some = cols[::3]
    assert np.allclose(kind.rows(problem, theta, some)[1], jac[:, some], rtol=0.0, atol=1e-12)
