"""A URDF without masses (MUKCa's Panda and iiwa14) borrows them: ``--inertias URDF``.

Without masses every gravity torque is zero, so compliance and backlash cannot be tried; the
diagnosis says so and names the option. With the masses of a URDF of the same robot, the gravity
torques are that URDF's, the kinematics and the robot's own URDF text are unchanged.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import pincal
from pincal.auto.diagnose import diagnose
from pincal.cli import main
from pincal.cli.flags import as_flags
from pincal.errors import RobotError
from pincal.kinematics.gravity import gravity_torques, massless
from pincal.robot.robots import bundled_urdf

HINT = "the URDF has no masses (lend them with inertias=URDF)"  # the command: --inertias URDF


@pytest.fixture(scope="module")
def bare_ur5(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The bundled UR5's URDF with every ``<inertial>`` taken out."""
    text = bundled_urdf("ur5").read_text()
    bare = re.sub(r"<inertial>.*?</inertial>", "", text, flags=re.DOTALL)
    assert "<inertial>" not in bare and bare != text
    path = tmp_path_factory.mktemp("bare") / "ur5_bare.urdf"
    path.write_text(bare)
    return path


def test_borrowed_masses_give_the_donors_gravity_torques(bare_ur5: Path) -> None:
    """Torques equal the donor's to 1e-12 N·m at random configurations; kinematics and the
    robot's URDF text are its own."""
    donor = pincal.load_robot("ur5")
    bare = pincal.load_robot(bare_ur5, tip=donor.tip)
    lent = pincal.load_robot(bare_ur5, tip=donor.tip, inertias="ur5")
    q = donor.random_configurations(20, np.random.default_rng(0))
    assert massless(bare) and not massless(lent)
    assert np.abs(gravity_torques(bare, q)).max() == 0.0
    expected = gravity_torques(donor, q)
    assert np.abs(expected).max() > 1.0  # [N·m]: the shoulder carries the arm
    np.testing.assert_allclose(gravity_torques(lent, q), expected, rtol=0, atol=1e-12)
    for qi in q:
        assert lent.frame_placement(qi).isApprox(bare.frame_placement(qi), 1e-14)
    assert lent.urdf_text == bare.urdf_text and "<inertial>" not in lent.urdf_text


def test_a_donor_sharing_no_link_is_refused(bare_ur5: Path) -> None:
    with pytest.raises(RobotError, match="inertias=panda: none of its links"):
        pincal.load_robot(bare_ur5, inertias="panda")
    with pytest.raises(RobotError, match="no such URDF file"):
        pincal.load_robot(bare_ur5, inertias=str(bare_ur5.with_name("missing.urdf")))


def test_diagnosis_names_what_it_could_not_try(bare_ur5: Path) -> None:
    """Without masses no compliance or backlash is a candidate and the summary says why; with
    them both are candidates and the note is gone."""
    robot = pincal.load_robot(bare_ur5, tip="tool0")
    data = pincal.simulate(robot, n_fit=40, n_test=0, seed=1)[1]
    found = diagnose(robot, data, folds=3)
    effects = {c.extension.effect for c in found.candidates}
    assert not effects & {"joint_compliance", "backlash"}
    assert found.untried is not None and found.summary().endswith(HINT)
    lent = diagnose(pincal.load_robot(bare_ur5, tip="tool0", inertias="ur5"), data, folds=3)
    assert {"joint_compliance", "backlash"} <= {c.extension.effect for c in lent.candidates}
    assert lent.untried is None and HINT not in lent.summary()


def test_cli_inertias_option(capsys: pytest.CaptureFixture[str], tmp_path: Path, bare_ur5: Path) -> None:
    """``pincal diagnose`` prints the note without ``--inertias`` and not with it; a donor that
    lends nothing is one error line, exit 2."""
    robot = pincal.load_robot(bare_ur5, tip="tool0")
    data = tmp_path / "data.csv"
    pincal.write_csv(data, pincal.simulate(robot, n_fit=40, n_test=0, seed=2)[1], units="mm")
    base = ["diagnose", str(bare_ur5), str(data), "--units", "mm", "--folds", "3"]
    outs = []
    for extra in ([], ["--inertias", "ur5"]):
        capsys.readouterr()
        assert main([*base, *extra]) == 0
        outs.append(capsys.readouterr().out)
    assert as_flags(HINT) in outs[0] and as_flags(HINT) not in outs[1]
    capsys.readouterr()
    assert main([*base, "--inertias", "panda"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("pincal: error: --inertias panda")
