"""Several placements of a socket fixture calibrated together (MUKCa's folders of placements).

A folder of placement folders, each of ``hole_<name>.csv``, reads as one data set whose points
are ``<placement>/<name>``; a known distance ``0,1=D`` holds in every placement; a model fitted on
several placements is judged on another one, whose points are named ``0``, ``1``. Properties:
the reader keeps every row with its own placement's point, the distances go to each placement,
and the calibration on two placements reaches the noise floor on a third, through the API and the
command line.
"""

from __future__ import annotations

import json
from dataclasses import replace
from functools import cache
from pathlib import Path

import numpy as np
import pytest

import pincal
from pincal.cli import main
from pincal.data.point_files import read_socket_folder
from pincal.identify.evaluation import misplaced_rows
from pincal.identify.fixed_points import placed_distances, point_errors
from pincal.report.report import placements, report_json, report_warnings
from pincal.simulation.truth import TrueRobot, ball_positions, points_truth, simulate_points

NOISE = 5e-5  # 1σ per coordinate of where the hand holds the ball [m]
DISTANCE = 0.05  # between the two sockets of the fixture [m]
#: Where the fixture stands in each placement: its first socket [m] and the direction to the
#: second (unit vectors), in the base frame.
PLACES = {
    "front": (np.array([0.45, 0.0, 0.25]), np.array([0.0, 1.0, 0.0])),
    "left": (np.array([0.10, 0.45, 0.15]), np.array([1.0, 0.0, 0.0])),
    "low": (np.array([0.30, -0.35, 0.10]), np.array([0.6, 0.8, 0.0])),
}
N_ROWS = 40  # per placement, half per socket
FLOOR_FACTOR = 1.3  # how far above the noise floor the held-out RMS may sit


def _sockets(place: str) -> np.ndarray:
    first, direction = PLACES[place]
    return np.array([first, first + DISTANCE * direction])


@cache
def _experiment() -> tuple[TrueRobot, dict[str, pincal.Dataset]]:
    """A seeded true UR5 and its rows at each placement of the fixture."""
    truth = points_truth(pincal.load_robot("ur5"), 3)
    data = {
        place: simulate_points(truth, _sockets(place), N_ROWS, NOISE, np.random.default_rng(k))
        for k, place in enumerate(PLACES)
    }
    return truth, data


def _write_folder(folder: Path, data: dict[str, pincal.Dataset]) -> Path:
    """MUKCa's layout: ``folder/<placement>/hole_<name>.csv``."""
    for place, rows in data.items():
        (folder / place).mkdir(parents=True)
        assert rows.labels is not None
        for k, name in enumerate(rows.point_names):
            np.savetxt(folder / place / f"hole_{name}.csv", rows.q[rows.labels == k], delimiter=",")
    return folder


def test_placed_distances() -> None:
    """As written when both points exist; per placement; a placement's back to a bare pair."""
    both = placed_distances(("0", "1"), (("0", "1", DISTANCE),))
    assert both == (("0", "1", DISTANCE),)
    names = ("a/0", "a/1", "b/0", "b/1", "c/0")
    each = placed_distances(names, (("0", "1", DISTANCE),))
    assert each == (("a/0", "a/1", DISTANCE), ("b/0", "b/1", DISTANCE))  # c has no point 1
    back = placed_distances(("0", "1"), each)
    assert back == (("0", "1", DISTANCE),)
    assert placed_distances(names, (("0", "7", DISTANCE),)) == (("0", "7", DISTANCE),)


def test_folder_of_placements_reads_every_row_at_its_own_point(tmp_path: Path) -> None:
    """Rows keep their joint values and their placement's point; names are ``place/socket``."""
    _, data = _experiment()
    robot = pincal.load_robot("ur5")
    read = read_socket_folder(_write_folder(tmp_path, data), robot.joint_names)
    assert read.point_names == tuple(f"{p}/{s}" for p in sorted(PLACES) for s in ("0", "1"))
    assert read.labels is not None and len(read) == N_ROWS * len(PLACES)
    for k, name in enumerate(read.point_names):
        place, _, socket = name.partition("/")
        own = data[place]
        assert own.labels is not None
        expected = own.q[own.labels == own.point_names.index(socket)]
        np.testing.assert_allclose(read.q[read.labels == k], expected, rtol=1e-15, atol=1e-15)


def test_mukca_tip_pose_files_are_not_read_as_sockets(tmp_path: Path) -> None:
    """MUKCa's recordings keep the robot's own tip poses beside the joints (``hole_0_pose.csv``:
    x,y,z and a quaternion, 7 numbers a row, as many as a Panda's joints): they are skipped, in
    one placement and in a folder of them, and a folder of nothing else is refused."""
    _, data = _experiment()
    robot = pincal.load_robot("ur5")
    folder = _write_folder(tmp_path / "plain", data)
    expected = read_socket_folder(folder, robot.joint_names)
    rng = np.random.default_rng(0)
    for place in PLACES:
        for socket in ("0", "1"):  # as many columns as joints: readable as joint values
            poses = rng.uniform(-0.5, 0.5, (N_ROWS // 2, robot.n_joints))
            np.savetxt(folder / place / f"hole_{socket}_pose.csv", poses, delimiter=",")
    read = read_socket_folder(folder, robot.joint_names)
    assert read.point_names == expected.point_names
    np.testing.assert_array_equal(read.q, expected.q)
    one = read_socket_folder(folder / "front", robot.joint_names)
    assert one.point_names == ("0", "1") and len(one) == N_ROWS
    only_poses = tmp_path / "poses"
    only_poses.mkdir()
    np.savetxt(only_poses / "hole_0_pose.csv", np.zeros((3, robot.n_joints)), delimiter=",")
    with pytest.raises(pincal.DataError, match="without hole_<name>.csv"):
        read_socket_folder(only_poses, robot.joint_names)


def test_two_placements_calibrate_to_the_noise_floor_of_a_third(tmp_path: Path) -> None:
    """Fitted on ``front`` and ``left`` together (a distance in each), judged on ``low``: within
    1.3x of the true robot's own score there, the distance error at the means' noise."""
    truth, data = _experiment()
    robot = pincal.load_robot("ur5")
    two = _write_folder(tmp_path, {p: data[p] for p in ("front", "left")})
    fitted = read_socket_folder(two, robot.joint_names)
    cal = pincal.calibrate(
        robot, fitted, "placements", params="auto", point_distances=(("0", "1", DISTANCE),), test=data["low"]
    )
    assert cal.measurement.point_distances == (
        ("front/0", "front/1", DISTANCE),
        ("left/0", "left/1", DISTANCE),
    )
    held = data["low"]
    floor = np.sqrt(np.mean(point_errors(ball_positions(truth, held.q)[0], held, ())[0] ** 2)) * 1e3
    assert cal.test_after is not None and cal.test_before is not None
    assert cal.test_before.rms_mm > 5 * floor
    assert cal.test_after.rms_mm <= FLOOR_FACTOR * floor, (cal.test_after.rms_mm, floor)
    assert cal.test_after.point_distance_error_mm is not None
    assert cal.test_after.point_distance_error_mm <= 4 * NOISE * 1e3 * np.sqrt(2 / (N_ROWS / 2))


def test_cli_calibrates_a_folder_of_placements(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """``pincal calibrate ur5 ROBOT_DIR --test PLACEMENT_DIR``: every placement fitted, the
    report's held-out figures those of the API's calibration."""
    _, data = _experiment()
    folder = _write_folder(tmp_path / "robot", {p: data[p] for p in ("front", "left")})
    test = _write_folder(tmp_path / "held", {"low": data["low"]}) / "low"
    report = tmp_path / "report.json"
    capsys.readouterr()
    args = ["calibrate", "ur5", folder, "--point-distance", "0,1=50", "--units", "mm"]
    code = main([str(a) for a in [*args, "--test", test, "--report", report]])
    err = capsys.readouterr().err
    assert code == 0, err
    written = json.loads(report.read_text())
    assert written["measure"] == "points" and written["n_poses"] == 2 * N_ROWS
    robot = pincal.load_robot("ur5")
    cal = pincal.calibrate(
        robot,
        read_socket_folder(folder, robot.joint_names),
        "placements",
        params="auto",
        outliers=6.0,
        point_distances=(("0", "1", DISTANCE),),
        test=read_socket_folder(test, robot.joint_names),
    )
    assert cal.test_after is not None
    assert np.isclose(written["test"]["after"]["rms_mm"], cal.test_after.rms_mm, rtol=1e-6)
    assert written["test"]["after"]["point_distance_error_mm"] is not None


def test_rows_are_named_by_their_file(tmp_path: Path) -> None:
    """Every row's name points at its own file and line: that line holds its joint values, also
    after a subset (the names survive outlier screening and --holdout)."""
    _, data = _experiment()
    robot = pincal.load_robot("ur5")
    folder = _write_folder(tmp_path, data)
    read = read_socket_folder(folder, robot.joint_names)
    part = read.subset(np.arange(3, len(read), 7))
    for dataset in (read, part):
        for row, q in zip(dataset.row_numbers, dataset.q):
            name = dataset.row_name(int(row))
            file, _, line = name.rpartition(" row ")
            values = np.loadtxt(folder / file, delimiter=",", ndmin=2)
            np.testing.assert_array_equal(values[int(line) - 1], q)
    single = read_socket_folder(folder / "left", robot.joint_names)
    assert single.row_name(N_ROWS // 2 + 1) == "hole_1.csv row 1"
    assert pincal.Dataset(read.joint_names, read.q, read.points).row_name(5) == "row 5"


def test_a_slipped_ball_is_named_by_its_file_and_row(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """A row of ``left/hole_1.csv`` recorded with the ball in the other socket (50 mm off): the
    outlier screen leaves it out, the summary names ``left/hole_1.csv row 4``, and a warning says
    it sits at point ``left/0``; the placement is not called suspect for it."""
    _, data = _experiment()
    folder = _write_folder(tmp_path, {p: data[p] for p in ("front", "left")})
    path = folder / "left" / "hole_1.csv"
    rows, other = np.loadtxt(path, delimiter=","), np.loadtxt(folder / "left" / "hole_0.csv", delimiter=",")
    rows[3] = other[0]
    np.savetxt(path, rows, delimiter=",")
    capsys.readouterr()
    args = ["calibrate", "ur5", folder, "--point-distance", "0,1=50", "--units", "mm", "--params", "all"]
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    assert code == 0, err
    left_out = [line for line in out.splitlines() if line.startswith("outliers left out")]
    assert len(left_out) == 1 and "left/hole_1.csv row 4 (" in left_out[0], out
    warned = [line for line in out.splitlines() if line.startswith("warning:")]
    assert len(warned) == 1, out
    assert "1 fitted rows filed under point left/1 sit at point left/0" in warned[0]
    assert warned[0].endswith(": left/hole_1.csv row 4")
    assert "1 left out (1 at another point)" in out and "suspect" not in out


def test_held_out_rows_at_the_other_socket_are_named(tmp_path: Path) -> None:
    """Three rows of the held-out placement's ``hole_0.csv`` recorded in socket 1: its errors
    count them (MUKCa's figure is over every row), and one warning names them as held-out rows
    at point 1, with their distances; the fitted data has none."""
    truth, data = _experiment()
    robot = pincal.load_robot("ur5")
    held = data["low"]
    assert held.labels is not None
    moved = held.labels.copy()
    moved[np.flatnonzero(held.labels == 1)[:3]] = 0
    wrong = replace(held, labels=moved)
    cal = pincal.calibrate(
        robot, data["front"], "placements", params="auto", point_distances=(("0", "1", DISTANCE),), test=wrong
    )
    said = report_warnings(cal, data["front"], wrong)
    assert len(said) == 1 and said[0].startswith("3 held-out rows filed under point 0 sit at point 1 ("), said
    found = misplaced_rows(cal.model, cal.measurement, cal.theta, wrong, cal.extension)
    assert sorted(m.row for m in found) == sorted(wrong.row_numbers[moved != held.labels].tolist())
    for m in found:
        assert (m.point, m.near) == ("0", "1") and m.at_mm < 10 * NOISE * 1e3
        assert abs(m.off_mm - DISTANCE * 1e3) < 1.0
    assert cal.test_after is not None and cal.test_after.point_mae_mm is not None
    assert cal.test_after.point_mae_mm > 2.0  # three rows 50 mm off in 40
    assert report_warnings(cal, data["front"], held) == []


def test_a_placement_whose_rows_scatter_is_named(tmp_path: Path) -> None:
    """Three placements, one recorded with the ball five times looser in its sockets (a fixture
    that moved): the report names that one, and only that one, with a warning; with every
    placement alike none is named. Each placement's distance error is its own pair's."""
    truth, data = _experiment()
    robot = pincal.load_robot("ur5")
    low = simulate_points(truth, _sockets("low"), N_ROWS, 5 * NOISE, np.random.default_rng(9))
    loose = dict(data, low=low)
    distances = (("0", "1", DISTANCE),)
    for rows, suspect in ((data, set()), (loose, {"low"})):
        fitted = read_socket_folder(_write_folder(tmp_path / str(len(suspect)), rows), robot.joint_names)
        cal = pincal.calibrate(
            robot, fitted, "placements", params="auto", outliers=6.0, point_distances=distances
        )
        each = placements(cal, fitted)
        assert [p.name for p in each] == sorted(PLACES)
        assert {p.name for p in each if p.suspect} == suspect
        for p in each:
            assert p.after.point_distance_error_mm is not None
            assert p.after.point_distance_error_mm < 10 * NOISE * 1e3  # its own pair, not another's
        warned = [w for w in report_warnings(cal, fitted) if w.startswith("placement")]
        assert len(warned) == len(suspect)
        written = json.loads(report_json(cal, fitted))
        assert [p["suspect"] for p in written["placements"]] == [p.suspect for p in each]


def test_errors_of_a_subset_holding_one_point_have_no_distance(tmp_path: Path) -> None:
    """A subset with the rows of one socket only: no distance error (there is no pair), the
    rows' errors those of the whole data's rows of that socket."""
    truth, data = _experiment()
    held = data["front"]
    assert held.labels is not None
    tips = ball_positions(truth, held.q)[0]
    rows, off = point_errors(tips, held, (("0", "1", DISTANCE),))
    assert len(off) == 1
    first = np.flatnonzero(held.labels == 0)
    part_rows, part_off = point_errors(tips[first], held.subset(first), (("0", "1", DISTANCE),))
    assert len(part_off) == 0
    np.testing.assert_allclose(part_rows, rows[first], rtol=1e-12)


def test_one_placement_is_told_to_record_more(tmp_path: Path) -> None:
    """Fixed points of one placement (50 mm apart) get a note to record placements spread over
    the workspace; a folder of placements, or points 0.5 m apart, get none."""
    truth, data = _experiment()
    robot = pincal.load_robot("ur5")
    distances = (("0", "1", DISTANCE),)
    folder = read_socket_folder(_write_folder(tmp_path, data), robot.joint_names)
    far = simulate_points(
        truth, np.array([[0.45, -0.25, 0.25], [0.45, 0.25, 0.25]]), N_ROWS, NOISE, np.random.default_rng(3)
    )
    for rows, noted in ((data["front"], True), (folder, False), (far, False)):
        given = distances if rows is not far else (("0", "1", 0.5),)
        cal = pincal.calibrate(robot, rows, "placements", params="auto", point_distances=given)
        assert ("note: the points lie within 0.2 m" in pincal.summary(cal, rows)) == noted
