"""pincal: kinematic calibration of robot arms on Pinocchio.

Load a robot, read or simulate measurements, calibrate, read the report::

    import pincal
    robot = pincal.load_robot("ur5")
    truth, fit, test = pincal.simulate(robot, n_fit=60, n_test=100, seed=0)
    cal = pincal.calibrate(robot, fit, model="placements", test=test)
    print(pincal.summary(cal))
"""

from .calibration import Calibration
from .checks import check_columns, check_limits, check_scale
from .choice import ModelChoice
from .compensate import Compensation, compensate_program, write_program
from .crossval import CrossValidation, cross_validate
from .data import Dataset, Targets, read_csv, read_program, write_csv
from .demo import gao2013_data
from .diagnose import Candidate, Diagnosis
from .effects import EFFECTS, Extension
from .errors import DataError, IdentifiabilityError, NotSupportedError, PincalError, RobotError
from .evaluation import ErrorStats, distance_errors, evaluate, pose_errors
from .identifiability import Identifiability
from .kinematics import Chain, forward, joint_jacobian, tip_jacobian
from .mdh import MdhModel, MdhTable, mdh_table
from .measurements import Measurement, Problem, all_pairs, gao_pairs
from .models import MODELS, Model, OffsetsModel, PlacementsModel, PoeModel, make_model
from .outliers import find_outliers, pose_scores
from .pipeline import calibrate
from .planning import Design, Plan, candidate_poses, plan_poses, write_poses
from .plots import plot_diagnosis
from .report import report_dict, report_json, summary
from .robots import BUNDLED, Robot, load_robot
from .selection import (
    Selection,
    SelectionCrossValidation,
    SelectionStep,
    cross_validate_selection,
    select_parameters,
)
from .simulate import TrueRobot, hide_effect, random_truth, simulate
from .tool import ToolCalibration, calibrate_tool, read_flange_poses
from .twists import Twists, chain_twists, gao_k, left_jacobian, nominal_twists, poe_forward
from .urdf_writer import CalibratedRobot, corrected_urdf, load_calibration, write_corrected_urdf

__version__ = "0.1.0"

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
    "MdhModel",
    "MdhTable",
    "Measurement",
    "Model",
    "ModelChoice",
    "NotSupportedError",
    "OffsetsModel",
    "PincalError",
    "PlacementsModel",
    "Plan",
    "PoeModel",
    "Problem",
    "Robot",
    "RobotError",
    "Selection",
    "SelectionCrossValidation",
    "SelectionStep",
    "Targets",
    "ToolCalibration",
    "TrueRobot",
    "Twists",
    "all_pairs",
    "calibrate",
    "calibrate_tool",
    "candidate_poses",
    "chain_twists",
    "check_columns",
    "check_limits",
    "check_scale",
    "compensate_program",
    "corrected_urdf",
    "cross_validate",
    "cross_validate_selection",
    "distance_errors",
    "evaluate",
    "find_outliers",
    "forward",
    "gao2013_data",
    "gao_k",
    "gao_pairs",
    "hide_effect",
    "joint_jacobian",
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
    "report_dict",
    "report_json",
    "select_parameters",
    "simulate",
    "summary",
    "tip_jacobian",
    "write_corrected_urdf",
    "write_csv",
    "write_poses",
    "write_program",
]
