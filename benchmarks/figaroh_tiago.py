"""FIGAROH 1.0.2 on the TIAGo Qualisys data, timed in-process (for alternating benchmarks).

Reproduces FIGAROH's held-out protocol (figaroh-examples ``examples/tiago/heldout_protocol.py``:
model ``full_params``, unknown base and tool frames, fitted on the 2021-11-30 session only) with
a config equivalent to ``tiago_unified_config.yaml`` and the cost function of the example's
``TiagoCalibration`` (SE(3) log-map residuals of point 1, columns x1, y1, z1).

FIGAROH is optional; install it into the project's venv with ``pip install figaroh==1.0.2``.
That leaves ``pin`` 4.1.0 and ``numpy`` 2.4.6 untouched (checked with ``--dry-run``) and adds
PyYAML, pandas, picos, cvxopt, ndcurves, libndcurves, meshcat, numdifftools, rospkg, catkin-pkg,
docutils, distro, pyngrok, u-msgpack-python. ``import figaroh`` imports every subpackage, so
``--no-deps`` would not save anything.

Unlike the example, the URDF is loaded with ``pin.buildModelFromUrdf`` (kinematics only): FIGAROH's
``load_robot`` also builds collision geometry and the TIAGo meshes are not in the dataset. FIGAROH
only uses ``robot.model``, ``robot.data`` and ``robot.q0``.

Usage: ``python benchmarks/figaroh_tiago.py DATASET_DIR`` (RMSEs, median identify() time, whole
script time) or ``python benchmarks/figaroh_tiago.py --script DATASET_DIR`` (the whole script once).
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import importlib.util
import io
import statistics
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np

URDF = "tiago_48_schunk.urdf"
TRAIN = "train_2021-11-30.csv"
VALIDATION = "validation_2021-11-26.csv"
JOINTS = ["torso_lift_joint"] + [f"arm_{i}_joint" for i in range(1, 8)]


def figaroh_available() -> bool:
    """Whether FIGAROH can be imported (without importing it)."""
    return importlib.util.find_spec("figaroh") is not None


def figaroh_config(train_csv: Path, level: str = "full_params") -> dict[str, Any]:
    """FIGAROH unified config, equivalent to the example's ``tiago_unified_config.yaml``.

    Args:
        train_csv: Training CSV (``source_file``).
        level: ``"full_params"`` (joint placements) or ``"joint_offset"``.

    Returns:
        The unified config as a dict, to be dumped to YAML.
    """
    return {
        "_metadata": {"schema_version": "2.0", "config_type": "robot_configuration"},
        "robot": {"name": "tiago", "properties": {"joints": {"active_joints": JOINTS}}},
        "tasks": {
            "calibration": {
                "enabled": True,
                "parameters": {
                    "calibration_level": level,
                    "include_non_geometric": False,
                    "outlier_threshold": 0.05,
                },
                "kinematics": {"base_frame": "universe", "tool_frame": "wrist_ft_tool_link"},
                "measurements": {
                    "markers": [{"name": "wrist_marker", "measurable_dof": [True] * 3 + [False] * 3}],
                    "poses": {
                        "base_pose": [0.0908, 0.08, 0.0, -1.57, 0.0, 0.0],
                        "tool_pose": [0.2163, 0.03484, 0.004, 0.0, -1.57, -1.57],
                    },
                },
                "data": {"source_file": str(train_csv.resolve()), "validation_data_file": ""},
            }
        },
    }


def _import_figaroh() -> Any:
    """Import FIGAROH's calibration module quietly (Agg backend, no converter warnings)."""
    import matplotlib

    matplotlib.use("Agg")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        from figaroh.calibration import base_calibration
    return base_calibration


class FigarohTiago:
    """FIGAROH's TIAGo mocap calibration, split into preparation and identification.

    Args:
        dataset_dir: Folder with the URDF and the train/validation CSVs.
        level: FIGAROH calibration model, ``"full_params"`` by default.
    """

    def __init__(self, dataset_dir: Path, level: str = "full_params") -> None:
        self.dataset_dir = Path(dataset_dir)
        self.level = level
        self.calib: Any = None

    def prepare(self) -> None:
        """Import FIGAROH, load the URDF, parse the config and read both CSVs (not timed)."""
        bc = _import_figaroh()
        import pinocchio as pin
        import yaml
        from figaroh.data.observations import PoseObservations

        base: Any = bc.BaseCalibration

        class TiagoCalibration(base):  # as in figaroh-examples' tiago_tools.py
            def cost_function(self, var: np.ndarray) -> np.ndarray:
                pee = bc.calc_updated_fkm(self.model, self.data, var, self.q_measured, self.calib_config)
                return self._compute_logmap_residuals(self.PEE_measured, pee)

        self._fkm = bc.calc_updated_fkm
        robot = pin.RobotWrapper(pin.buildModelFromUrdf(str(self.dataset_dir / URDF)))
        with tempfile.TemporaryDirectory() as tmp:
            cfg_path = Path(tmp) / "tiago_config.yaml"
            cfg_path.write_text(yaml.safe_dump(figaroh_config(self.dataset_dir / TRAIN, self.level)))
            self.calib = TiagoCalibration(robot, str(cfg_path))
        cfg = self.calib.calib_config
        cfg["known_baseframe"] = False  # base-to-mocap transform and tool point are unknowns
        cfg["known_tipframe"] = False
        self.calib.load_data_set()  # first half of initialize(): reads the training CSV
        self._template = copy.deepcopy(cfg)
        obs = PoseObservations.from_csv(self.dataset_dir / VALIDATION, robot.model, cfg)
        self._validation = obs.to_legacy(robot.model, cfg)

    def identify(self) -> float:
        """Run FIGAROH's identification on the training data; repeatable.

        Equivalent of the example's ``initialize()`` (minus reading the CSV, done in
        :meth:`prepare`) and ``solve()``: structural parameter selection and elimination of the
        parameters absorbed by the frames, then Levenberg-Marquardt with outlier check and
        FIGAROH's own evaluation (its printed report goes to a discarded buffer).

        Returns:
            Train RMSE of the 3-D error of point 1 [mm].
        """
        if self.calib is None:
            self.prepare()
        calib = self.calib
        calib.calib_config = copy.deepcopy(self._template)  # create_param_list mutates it
        calib.stages = []
        with contextlib.redirect_stdout(io.StringIO()):
            calib.create_param_list()
            calib.solve(plotting=False, enable_logging=False, html_report=False)
        return self._rmse(calib.q_measured, calib.PEE_measured)

    @property
    def n_params(self) -> int:
        """Number of parameters FIGAROH identified (after elimination)."""
        return len(self.calib.LM_result.x)

    def validation_rmse(self) -> float:
        """RMSE [mm] of point 1 on the validation session, with the last identified model."""
        pee, q = self._validation
        return self._rmse(q, pee)

    def _rmse(self, q: np.ndarray, pee: np.ndarray) -> float:
        cfg = dict(self.calib.calib_config, NbSample=len(q))
        pred = self._fkm(self.calib.model, self.calib.data, self.calib.LM_result.x, q, cfg)
        err = (pred - pee).reshape(3, -1)
        return float(np.sqrt(np.mean(np.sum(err**2, axis=0))) * 1000.0)


def time_whole_script(dataset_dir: Path) -> float:
    """Wall-clock seconds of a fresh ``python figaroh_tiago.py --script DIR`` subprocess.

    Args:
        dataset_dir: Folder with the TIAGo data.

    Returns:
        Seconds from process start to exit (import, load, identify, print).
    """
    t0 = time.perf_counter()
    subprocess.run(
        [sys.executable, str(Path(__file__).resolve()), "--script", str(dataset_dir)],
        check=True,
        stdout=subprocess.DEVNULL,
    )
    return time.perf_counter() - t0


def main(argv: list[str] | None = None) -> None:
    """Command-line entry point."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dataset_dir", type=Path)
    parser.add_argument("--script", action="store_true", help="run FIGAROH's whole script once")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args(argv)
    if not figaroh_available():
        sys.exit("figaroh is not installed: pip install figaroh==1.0.2")
    bench = FigarohTiago(args.dataset_dir)
    if args.script:
        print(f"train RMSE {bench.identify():.2f} mm")
        return
    bench.prepare()
    times = []
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        train = bench.identify()
        times.append(time.perf_counter() - t0)
    print(f"FIGAROH full_params ({bench.n_params} parameters)")
    print(f"train RMSE {train:.2f} mm, validation RMSE {bench.validation_rmse():.2f} mm")
    print(f"identify(): median {statistics.median(times):.3f} s over {args.repeats} runs")
    print(f"whole script: {time_whole_script(args.dataset_dir):.2f} s")


if __name__ == "__main__":
    main()
