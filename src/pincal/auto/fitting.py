"""One fit, in two steps: the fit at the default pull (:func:`first_fit`), then the pull chosen and
the fit judged (:meth:`Based.protected`, :func:`pincal.identify.guard.protect`).

The outlier screen looks at the first step's fit whenever the evidence chooses the pull (see
:attr:`pincal.identify.guard.Protected.screening`), so a call that finds outliers leaves them
out and starts again before it chooses a pull or runs the guard on poses it will not keep. On
large data it starts from the fit of the random subset of poses its robust fit runs on
(:func:`sample_fit`), before any fit of every pose.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from pincal.identify import chunked
from pincal.identify.guard import DEFAULT_PULL, Protected, Pull, protect
from pincal.identify.identifiability import RCOND, Identifiability
from pincal.identify.prior import fixed_weight
from pincal.identify.solver import Setup, identifiable_set, register, solve
from pincal.identify.warm import WarmStart, fits_better


@dataclass(frozen=True, eq=False)
class Based:
    """A fit at the default pull, before its pull is chosen and the guard judges it.

    Attributes:
        setup: the problem, at the default pull.
        nominal: the registration-only θ.
        identifiability: the identifiable set: the unknowns fitted.
        base: the fit at the default pull.
        pull, loss, f_scale: how the fit goes on (:func:`pincal.identify.guard.protect`).
    """

    setup: Setup
    nominal: np.ndarray
    identifiability: Identifiability
    base: np.ndarray
    pull: Pull
    loss: str
    f_scale: float

    @property
    def free(self) -> np.ndarray:
        """Mask of the fitted unknowns."""
        return self.identifiability.identifiable

    @property
    def screening(self) -> tuple[Setup, np.ndarray] | None:
        """The problem and fit the outliers are screened on, when known before the pull is chosen:
        the default pull's fit whenever the evidence chooses the pull (None: the fit at the pull)."""
        if fixed_weight(self.setup, self.free, self.pull.weight, self.loss) is not None:
            return None
        return self.setup, self.base

    def protected(self) -> Protected:
        """The pull chosen, the fit at it, and the guard's verdict."""
        ident, how = self.identifiability, (self.pull, self.loss, self.f_scale)
        return protect(self.setup, self.nominal, ident, self.base, *how)

    def screened_on(self) -> tuple[Setup, np.ndarray]:
        """The problem and fit the outliers are screened on (after the pull when it must be)."""
        early = self.screening
        return self.protected().screening if early is None else early


def first_fit(
    setup: Setup,
    params: Sequence[str] | None,
    *,
    partial: bool = False,
    loss: str = "linear",
    f_scale: float = 1e-4,
    rcond: float = RCOND,
    nominal: np.ndarray | None = None,
    every: Identifiability | None = None,
    pull: Pull = DEFAULT_PULL,
    start: WarmStart | None = None,
) -> Based:
    """Register (unless the registration-only θ ``nominal`` is given), find the identifiable set
    (``every``, when given, is the one of every parameter at ``nominal``: used for ``params``
    None) and solve at the default pull; the fit begins at the fit ``start`` when given
    (:mod:`pincal.identify.warm`: the same minimum, in fewer steps), else at the nominal model."""
    nominal = register(setup) if nominal is None else nominal  # its first guess is as good a start
    known = every if params is None else None
    ident = identifiable_set(setup, nominal, params, partial, rcond) if known is None else known
    first = nominal if start is None else _warm(setup, start, nominal, ident.identifiable)
    base, _ = solve(setup, first, ident.identifiable, loss, f_scale)  # at the default pull
    return Based(setup, nominal, ident, base, pull, loss, f_scale)


def sample_fit(setup: Setup, params: Sequence[str] | None, options: dict[str, Any]) -> Based | None:
    """On a large problem (:func:`pincal.identify.chunked.is_large`), the fit (:func:`first_fit`, with
    ``options``) of the random subset of poses that the outlier screen's robust fit runs on
    (:func:`pincal.identify.chunked.sampled`), when the screen looks at the default pull's fit:
    the screen then starts from it, before any fit of every pose, which a call that finds
    outliers would make again without them. Else None."""
    if not chunked.is_large(setup.problem):
        return None
    pull, loss = options.get("pull", DEFAULT_PULL), options.get("loss", "linear")
    pulled = np.ones(setup.problem.n_params, dtype=bool)  # a given pull or a robust loss: no subset fit
    if fixed_weight(setup, pulled, pull.weight, loss) is not None:
        return None
    sampled = first_fit(chunked.sampled(setup), params, **options)
    return sampled if sampled.screening is not None else None


def fit(setup: Setup, params: Sequence[str] | None, **options: Any) -> Protected:
    """:func:`first_fit` (same arguments), then the pull chosen and the fit judged against the
    nominal model (:func:`pincal.identify.guard.protect`)."""
    return first_fit(setup, params, **options).protected()


def _warm(setup: Setup, start: WarmStart, nominal: np.ndarray, free: np.ndarray) -> np.ndarray:
    """Where a fit of the unknowns ``free`` begins: at ``start``, or at the registration-only θ
    ``nominal`` when that fits the poses better."""
    warm = start.fit(setup.problem, nominal, free)
    return warm if fits_better(setup.problem, warm, nominal) else nominal
