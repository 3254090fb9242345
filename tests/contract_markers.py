"""Reading a calibration of several markers by ``contracts.md`` alone (never importing pincal): the
URDF with the sidecar's ``instrument_T_base`` and ``markers`` (each marker's frame and point), the
joints of the sidecar's ``joints`` actuated and every other joint locked at neutral.

An independent reader, as outside tests read the files: the report's ``after`` and ``exported`` of
a calibration without effects must be reproduced by it.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pinocchio as pin
from marker_simulation import configuration


def predict(sidecar: str | Path, q: np.ndarray) -> dict[str, np.ndarray]:
    """Each marker's predicted points (N, 3) [m] in the instrument frame for joint values (N, n)."""
    side = json.loads(Path(sidecar).read_text())
    full = pin.buildModelFromUrdf(str(Path(sidecar).parent / side["urdf"]))
    keep = {full.getJointId(j) for j in side["joints"]}
    lock = [j for j in range(1, full.njoints) if j not in keep]
    model = pin.buildReducedModel(full, lock, pin.neutral(full)) if lock else full
    assert list(model.names[1:]) == list(side["joints"]), "the sidecar's joints in the URDF's order"
    reg = np.array(side["instrument_T_base"]["matrix"])
    data = model.createData()
    out = {k: np.empty((len(q), 3)) for k in side["markers"]}
    for i, qi in enumerate(q):
        pin.framesForwardKinematics(model, data, configuration(model, qi))
        for k, marker in side["markers"].items():
            point = data.oMf[model.getFrameId(marker["frame"])].act(np.array(marker["point_m"]))
            out[k][i] = reg[:3, :3] @ point + reg[:3, 3]
    return out


def rms_mm(
    sidecar: str | Path, q: np.ndarray, labels: list[str], points: np.ndarray
) -> tuple[float, dict[str, float]]:
    """The RMS [mm] over every measured point (NaN: not seen), and each marker's."""
    predicted = predict(sidecar, q)
    errors = {k: np.sum((predicted[k] - points[:, c]) ** 2, axis=1) for c, k in enumerate(labels)}
    each = {k: float(np.sqrt(np.nanmean(e))) * 1e3 for k, e in errors.items()}
    return float(np.sqrt(np.nanmean(np.concatenate(list(errors.values()))))) * 1e3, each
