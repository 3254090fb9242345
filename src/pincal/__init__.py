"""pincal: kinematic calibration of robot arms on Pinocchio.

Load a robot, read or simulate measurements, calibrate, read the report::

    import pincal
    robot = pincal.load_robot("ur5")
    truth, fit, test = pincal.simulate(robot, n_fit=60, n_test=100, seed=0)
    cal = pincal.calibrate(robot, fit, model="placements", test=test)
    print(pincal.summary(cal))

The names below are the public API; everything else lives in the sub-packages (``pincal.robot``,
``pincal.kinematics``, ``pincal.data``, ``pincal.identify``, ``pincal.auto``, ...), layered so
that each imports only the ones below it (``[tool.importlinter]`` in ``pyproject.toml``).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from .errors import (
    DataError,
    IdentifiabilityError,
    ImplausibleError,
    NotSupportedError,
    OutputError,
    PincalError,
    RobotError,
)
from .options import MODELS

if TYPE_CHECKING:  # for type checkers (``as``: re-exported); at run time each loads on first use (_LAZY)
    from .auto.diagnose import Diagnosis as Diagnosis
    from .auto.diagnose import diagnose as diagnose
    from .auto.pipeline import calibrate as calibrate
    from .auto.settings import CalibrateOptions as CalibrateOptions
    from .data.csv_writer import write_csv as write_csv
    from .data.dataset import Dataset as Dataset
    from .data.dataset import read_csv as read_csv
    from .demo import gao2013_data as gao2013_data
    from .export.calibrated_robot import CalibratedRobot as CalibratedRobot
    from .export.calibrated_robot import load_calibration as load_calibration
    from .export.compensate import Compensation as Compensation
    from .export.compensate import compensate_program as compensate_program
    from .export.ur_yaml import write_ur_kinematics as write_ur_kinematics
    from .export.urdf_writer import write_corrected_urdf as write_corrected_urdf
    from .identify.calibration import Calibration as Calibration
    from .identify.evaluation import ErrorStats as ErrorStats
    from .identify.guard import Pull as Pull
    from .kinematics.effects import EFFECTS as EFFECTS
    from .kinematics.effects import Extension as Extension
    from .planning.plan import Plan as Plan
    from .planning.plan import plan_poses as plan_poses
    from .plausibility.judge import judge_calibration as judge_calibration
    from .report.report import report_dict as report_dict
    from .report.summary_table import summary as summary
    from .robot.robots import Robot as Robot
    from .robot.robots import load_robot as load_robot
    from .robot.ur_frames import read_ur_kinematics as read_ur_kinematics
    from .simulation.truth import random_truth as random_truth
    from .simulation.truth import simulate as simulate
    from .tool.tcp import ToolCalibration as ToolCalibration
    from .tool.tcp import calibrate_tool as calibrate_tool

__version__ = "0.1.0"

#: Where each public name lives: ``import pincal`` stays light (``pincal --help`` loads no NumPy).
_LAZY: dict[str, str] = {
    "Diagnosis": "auto.diagnose",
    "diagnose": "auto.diagnose",
    "calibrate": "auto.pipeline",
    "CalibrateOptions": "auto.settings",
    "Dataset": "data.dataset",
    "read_csv": "data.dataset",
    "write_csv": "data.csv_writer",
    "gao2013_data": "demo",
    "CalibratedRobot": "export.calibrated_robot",
    "load_calibration": "export.calibrated_robot",
    "Compensation": "export.compensate",
    "compensate_program": "export.compensate",
    "write_ur_kinematics": "export.ur_yaml",
    "write_corrected_urdf": "export.urdf_writer",
    "Calibration": "identify.calibration",
    "ErrorStats": "identify.evaluation",
    "Pull": "identify.guard",
    "EFFECTS": "kinematics.effects",
    "Extension": "kinematics.effects",
    "Plan": "planning.plan",
    "plan_poses": "planning.plan",
    "judge_calibration": "plausibility.judge",
    "report_dict": "report.report",
    "summary": "report.summary_table",
    "Robot": "robot.robots",
    "load_robot": "robot.robots",
    "read_ur_kinematics": "robot.ur_frames",
    "random_truth": "simulation.truth",
    "simulate": "simulation.truth",
    "ToolCalibration": "tool.tcp",
    "calibrate_tool": "tool.tcp",
}

__all__ = [
    "DataError",
    "IdentifiabilityError",
    "ImplausibleError",
    "NotSupportedError",
    "OutputError",
    "PincalError",
    "RobotError",
    "MODELS",
    *_LAZY,
    "__version__",
]


def __getattr__(name: str) -> Any:
    if name not in _LAZY:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
