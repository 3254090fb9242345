"""How many poses a plan needs: independent equations against identifiable parameters, with
some to spare for the calibration's cross-validation and outlier screen."""

from __future__ import annotations

import math

from pincal.errors import IdentifiabilityError
from pincal.identify.kinds import get_kind


def independent_equations(measure: str, n_poses: int) -> int:
    """Independent equations of ``n_poses`` poses: 3 or 6 each, and for distances between N
    points at most their 3N - 6 coordinates up to a rigid motion (and at most N(N-1)/2 pairs)."""
    kind = get_kind(measure)
    if kind.by_pairs:
        return max(0, min(3 * n_poses - 6, n_poses * (n_poses - 1) // 2))
    return n_poses * kind.width


#: The share of the poses a calibration may fit without: ``calibrate``'s cross-validation
#: (``--extend auto``, 5 folds) fits on four fifths of them, and its outlier screen drops some.
SPARE_SHARE = 0.2


def safe_poses(measure: str, n_free: int) -> int:
    """The fewest poses that leave more independent equations than ``n_free`` identifiable
    parameters after a fifth of them (rounded up, at least one pose) is left out: about 1.25
    times as many equations as parameters, and at least a pose's equations to spare."""
    n = 1
    while independent_equations(measure, n - math.ceil(SPARE_SHARE * n)) <= n_free:
        n += 1
    return n


def check_equations(measure: str, n_poses: int, n_free: int) -> tuple[str, ...]:
    """Refuse a plan with no more independent equations than identifiable parameters; warn of
    one with too few to spare (:func:`safe_poses`), which the calibration refuses, or cannot
    cross-validate, once an outlier or a fold is left out. Returns the warnings."""
    given, need = independent_equations(measure, n_poses), safe_poses(measure, n_free)
    said = f"{n_poses} poses give {given} independent equations for {n_free} identifiable parameters"
    if given <= n_free:
        least = next(n for n in range(n_poses, need + 1) if independent_equations(measure, n) > n_free)
        raise IdentifiabilityError(f"{said}: plan more poses (at least {least}; {need} for a safe margin)")
    if n_poses >= need:
        return ()
    return (
        f"{said}, a thin margin: calibrate refuses them if it leaves out an outlier or a "
        f"cross-validation fold; plan {need} poses or more for a safe margin",
    )
