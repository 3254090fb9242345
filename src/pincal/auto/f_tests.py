"""The F-tests of a diagnosis (:mod:`pincal.auto.diagnosis`): does a candidate's fit lower the
residuals more than its extra parameters would by chance?

For distance data the test counts ``3 N - 6`` independent equations for ``N`` poses, since the
distances of all pairs carry no more information than the points themselves.
"""

from __future__ import annotations

from pincal.auto.screening import Linearised, Screen
from pincal.data.dataset import Dataset
from pincal.identify.calibration import Calibration


def _counted(sum_sq: float, n_res: int, pairs: bool, n_poses: int) -> tuple[float, int]:
    """A residual sum of squares and its number of independent equations: for distance data,
    the ``3 N - 6`` that the pairs' distances carry (``pairs``), the sum scaled to match."""
    if not pairs:
        return sum_sq, n_res
    n_eq = 3 * n_poses - 6
    return sum_sq * n_eq / n_res, n_eq


def _rss(cal: Calibration, data: Dataset) -> tuple[float, int]:
    """Residual sum of squares of a fit and its number of independent equations."""
    res = cal.problem(data).residuals(cal.theta)
    return _counted(float(res @ res), len(res), cal.measurement.measure.by_pairs, len(data))


def _f_value(rss0: float, rss1: float, extra: int, dof: int) -> float:
    """p-value of the F-test of ``extra`` more parameters, ``dof`` residual degrees of freedom."""
    if extra <= 0 or dof <= 0 or rss1 <= 0:
        return 1.0
    from scipy.special import fdtrc  # here: SciPy's special functions are start-up a run may not pay

    return float(fdtrc(extra, dof, ((rss0 - rss1) / extra) / (rss1 / dof)))


def f_test(base: Calibration, ext: Calibration, data: Dataset) -> float:
    """p-value of the F-test of the extended fit ``ext`` against the baseline ``base`` on ``data``."""
    rss0, n_eq = _rss(base, data)
    rss1, _ = _rss(ext, data)
    extra = ext.identifiability.n_identifiable - base.identifiability.n_identifiable
    return _f_value(rss0, rss1, extra, n_eq - ext.identifiability.n_identifiable)


def f_screened(base: Calibration, lin: Linearised, screen: Screen, extra: int) -> float:
    """The F-test of a candidate only screened: its linearised fit's residual sum against the
    base's (whose residuals ``lin`` holds)."""
    kind, n_poses, n_res = lin.kind.by_pairs, len(lin.data), len(lin.residuals)
    rss0, n_eq = _counted(float(lin.residuals @ lin.residuals), n_res, kind, n_poses)
    rss1, _ = _counted(screen.rss, n_res, kind, n_poses)
    return _f_value(rss0, rss1, extra, n_eq - base.identifiability.n_identifiable - extra)
