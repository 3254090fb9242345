"""pincal: kinematic calibration of robot arms on Pinocchio.

Load a robot, read or simulate measurements, calibrate, read the report::

    import pincal
    robot = pincal.load_robot("ur5")
    truth, fit, test = pincal.simulate(robot, n_fit=60, n_test=100, seed=0)
    cal = pincal.calibrate(robot, fit, model="placements", test=test)
    print(pincal.summary(cal))
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
from .options import BUNDLED, MODELS

if TYPE_CHECKING:  # the same names for type checkers; at run time each loads on first use
    from .calibrated_robot import CalibratedRobot, load_calibration
    from .calibration import Calibration
    from .checks import check_columns, check_limits, check_scale
    from .choice import ModelChoice
    from .compensate import Compensation, compensate_program, write_program
    from .crossval import CrossValidation, cross_validate
    from .data import Dataset, Targets, read_csv, read_program, write_csv
    from .demo import gao2013_data
    from .descriptions import xacro_to_urdf
    from .diagnose import Candidate, Diagnosis
    from .effects import EFFECTS, Extension
    from .evaluation import ErrorStats, distance_errors, evaluate, pose_errors
    from .guard import Pull
    from .identifiability import Identifiability
    from .kinematics import Chain, forward, joint_jacobian, tip_jacobian
    from .mdh import MdhModel, MdhTable, make_model, mdh_table
    from .measurements import Measurement, Problem, all_pairs, gao_pairs
    from .models import Model, OffsetsModel, PlacementsModel, PoeModel
    from .outliers import find_outliers, pose_scores
    from .pipeline import calibrate
    from .planning import Design, Plan, candidate_poses, plan_poses, write_poses
    from .plausibility import judge_calibration
    from .plots import plot_diagnosis
    from .report import report_dict, report_json
    from .robots import Robot, load_robot
    from .selection import (
        Selection,
        SelectionCrossValidation,
        SelectionStep,
        cross_validate_selection,
        select_parameters,
    )
    from .simulation import TrueRobot, hide_effect, points_truth, random_truth, simulate, simulate_points
    from .summary_table import summary
    from .tool import ToolCalibration, calibrate_tool, read_flange_poses
    from .tool_plausibility import judge_tool
    from .twists import Twists, chain_twists, gao_k, left_jacobian, nominal_twists, poe_forward
    from .ur_yaml import (
        URKinematics,
        calibrated_ur_kinematics,
        default_ur_kinematics,
        read_ur_kinematics,
        write_ur_kinematics,
    )
    from .urdf_writer import corrected_urdf, write_corrected_urdf
    from .verdict import Check, Verdict, robot_size

__version__ = "0.1.0"

#: Where each public name lives: ``import pincal`` stays light (``pincal --help`` loads no NumPy).
_LAZY: dict[str, str] = {
    "Calibration": "calibration",
    "check_columns": "checks",
    "check_limits": "checks",
    "check_scale": "checks",
    "ModelChoice": "choice",
    "Compensation": "compensate",
    "compensate_program": "compensate",
    "write_program": "compensate",
    "CrossValidation": "crossval",
    "cross_validate": "crossval",
    "Dataset": "data",
    "Targets": "data",
    "read_csv": "data",
    "read_program": "data",
    "write_csv": "data",
    "gao2013_data": "demo",
    "Candidate": "diagnose",
    "Diagnosis": "diagnose",
    "EFFECTS": "effects",
    "Extension": "effects",
    "ErrorStats": "evaluation",
    "distance_errors": "evaluation",
    "evaluate": "evaluation",
    "pose_errors": "evaluation",
    "Identifiability": "identifiability",
    "Chain": "kinematics",
    "forward": "kinematics",
    "joint_jacobian": "kinematics",
    "tip_jacobian": "kinematics",
    "MdhModel": "mdh",
    "MdhTable": "mdh",
    "mdh_table": "mdh",
    "Measurement": "measurements",
    "Problem": "measurements",
    "all_pairs": "measurements",
    "gao_pairs": "measurements",
    "Model": "models",
    "OffsetsModel": "models",
    "PlacementsModel": "models",
    "PoeModel": "models",
    "make_model": "mdh",
    "find_outliers": "outliers",
    "pose_scores": "outliers",
    "calibrate": "pipeline",
    "Pull": "guard",
    "judge_calibration": "plausibility",
    "judge_tool": "tool_plausibility",
    "Check": "verdict",
    "Verdict": "verdict",
    "robot_size": "verdict",
    "Design": "planning",
    "Plan": "planning",
    "candidate_poses": "planning",
    "plan_poses": "planning",
    "write_poses": "planning",
    "plot_diagnosis": "plots",
    "report_dict": "report",
    "report_json": "report",
    "summary": "summary_table",
    "Robot": "robots",
    "load_robot": "robots",
    "Selection": "selection",
    "SelectionCrossValidation": "selection",
    "SelectionStep": "selection",
    "cross_validate_selection": "selection",
    "select_parameters": "selection",
    "TrueRobot": "simulation",
    "hide_effect": "simulation",
    "random_truth": "simulation",
    "simulate": "simulation",
    "simulate_points": "simulation",
    "points_truth": "simulation",
    "ToolCalibration": "tool",
    "calibrate_tool": "tool",
    "read_flange_poses": "tool",
    "Twists": "twists",
    "chain_twists": "twists",
    "gao_k": "twists",
    "left_jacobian": "twists",
    "nominal_twists": "twists",
    "poe_forward": "twists",
    "CalibratedRobot": "calibrated_robot",
    "corrected_urdf": "urdf_writer",
    "load_calibration": "calibrated_robot",
    "write_corrected_urdf": "urdf_writer",
    "URKinematics": "ur_yaml",
    "calibrated_ur_kinematics": "ur_yaml",
    "default_ur_kinematics": "ur_yaml",
    "read_ur_kinematics": "ur_yaml",
    "write_ur_kinematics": "ur_yaml",
    "xacro_to_urdf": "descriptions",
}

__all__ = [
    "BUNDLED",
    "EFFECTS",
    "MODELS",
    "CalibratedRobot",
    "Calibration",
    "Candidate",
    "Chain",
    "Compensation",
    "CrossValidation",
    "DataError",
    "Dataset",
    "Design",
    "Diagnosis",
    "ErrorStats",
    "Extension",
    "Identifiability",
    "IdentifiabilityError",
    "ImplausibleError",
    "MdhModel",
    "MdhTable",
    "Measurement",
    "Model",
    "ModelChoice",
    "NotSupportedError",
    "OffsetsModel",
    "OutputError",
    "PincalError",
    "PlacementsModel",
    "Plan",
    "PoeModel",
    "Pull",
    "Problem",
    "Robot",
    "RobotError",
    "Selection",
    "SelectionCrossValidation",
    "SelectionStep",
    "Targets",
    "ToolCalibration",
    "Verdict",
    "Check",
    "TrueRobot",
    "Twists",
    "URKinematics",
    "all_pairs",
    "calibrate",
    "calibrate_tool",
    "calibrated_ur_kinematics",
    "candidate_poses",
    "chain_twists",
    "check_columns",
    "check_limits",
    "check_scale",
    "compensate_program",
    "corrected_urdf",
    "cross_validate",
    "cross_validate_selection",
    "default_ur_kinematics",
    "distance_errors",
    "evaluate",
    "find_outliers",
    "forward",
    "gao2013_data",
    "gao_k",
    "gao_pairs",
    "hide_effect",
    "joint_jacobian",
    "judge_calibration",
    "judge_tool",
    "left_jacobian",
    "load_calibration",
    "load_robot",
    "make_model",
    "mdh_table",
    "nominal_twists",
    "plan_poses",
    "plot_diagnosis",
    "poe_forward",
    "pose_errors",
    "pose_scores",
    "random_truth",
    "read_csv",
    "read_flange_poses",
    "read_program",
    "read_ur_kinematics",
    "robot_size",
    "report_dict",
    "report_json",
    "select_parameters",
    "simulate",
    "simulate_points",
    "points_truth",
    "summary",
    "tip_jacobian",
    "write_corrected_urdf",
    "write_csv",
    "write_poses",
    "write_program",
    "write_ur_kinematics",
    "xacro_to_urdf",
]


def __getattr__(name: str) -> Any:
    """Load a public name (or a submodule, ``pincal.diagnose``) on first use."""
    if name in _LAZY:
        value = getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    else:
        try:
            value = importlib.import_module(f".{name}", __name__)
        except ModuleNotFoundError as exc:
            if exc.name != f"{__name__}.{name}":  # a submodule that failed to import: say why
                raise
            raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
