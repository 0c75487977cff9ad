"""Nonlinear least squares for the few parameters fitted on the robot: Levenberg-Marquardt.

One solver serves the head calibration, the gaze (inverse kinematics) and the box fit. It is
numpy only: scipy.optimize would put about 140 MB on the robot's disk and 40-50 MB in a
long-running daemon's memory for the dozen parameters solved here.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

Residuals = Callable[[np.ndarray], np.ndarray]
"""Rows of parameters (k, n) to rows of residuals (k, m): a Jacobian's columns in one call."""


def row_by_row(residuals: Callable[[np.ndarray], np.ndarray]) -> Residuals:
    """A :data:`Residuals` from a function of one parameter vector, called once per row."""
    return lambda rows: np.array([residuals(p) for p in rows])


def levenberg_marquardt(
    residuals: Residuals,
    start: np.ndarray,
    tolerance: float = 1e-10,
    most: int = 500,
    lower: np.ndarray | None = None,
    upper: np.ndarray | None = None,
    huber: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The parameters near ``start`` that minimise ``|residuals(p)|^2``, and the residuals there.

    Levenberg-Marquardt with Marquardt's diagonal scaling and a forward-difference Jacobian, as
    MINPACK's ``lmdif`` (scipy's ``least_squares(method="lm")``) does.

    ``lower``/``upper`` bound the parameters (``start`` is clipped into them): a step is clipped
    to the box and a parameter held at a bound its gradient pushes against takes no part in the
    step, so a bounded minimum is found at the bound. ``huber`` makes the loss robust: residuals
    beyond ``huber`` count linearly, not squared (scipy's ``loss="huber", f_scale=huber``),
    solved by Gauss-Newton steps on that loss.
    """
    bounded = lower is not None or upper is not None
    lo = np.full(len(start), -np.inf) if lower is None else np.asarray(lower, dtype=float)
    hi = np.full(len(start), np.inf) if upper is None else np.asarray(upper, dtype=float)
    p = np.asarray(start, dtype=float).copy()
    if bounded:
        p = np.clip(p, lo, hi)
    r = residuals(p[None])[0]
    cost = _cost(r, huber)
    damping = 1e-3
    for _ in range(most):
        steps = np.sqrt(np.finfo(float).eps) * np.maximum(1.0, np.abs(p))
        if bounded:
            # A step out of the box goes the other way (the box is wider than the step).
            steps = np.where(p + steps > hi, -steps, steps)
        # Row i: p with its i-th parameter moved by steps[i]. Laid out by rows (the transpose
        # copied), as the products below take it: another layout sums them in another order.
        J = np.ascontiguousarray(((residuals(p + np.diag(steps)) - r) / steps[:, None]).T)
        if huber is None:
            A, g = J.T @ J, J.T @ r
            size = np.diag(A)
        else:
            # Gauss-Newton on Huber's loss itself, as scipy's least_squares scales it: the
            # gradient weighs each residual by the loss's slope, the curvature counts only the
            # residuals on its quadratic part (beyond ``huber`` the loss is straight).
            # Reweighting the curvature as well (IRLS) overstates it and the steps crawl: 500
            # of them ended short of the minimum. Marquardt's scale still takes every residual,
            # by its weight, so that the damping has a size when none is on the quadratic part.
            slope = _huber_weights(r, huber)
            curved = (np.abs(r) <= huber).astype(float)
            A, g = (J * curved[:, None]).T @ J, J.T @ (slope * r)
            size = (J * J).T @ slope
        # Held: at a bound that the descent (-g) points out of.
        free = ~(((p <= lo) & (g > 0)) | ((p >= hi) & (g < 0)))
        if np.max(np.abs(g[free]), initial=0.0) <= tolerance:
            break
        if not free.all():
            A, g, size = A[np.ix_(free, free)], g[free], size[free]
        scale = np.diag(np.maximum(size, 1e-12))
        while True:
            try:
                delta = np.linalg.solve(A + damping * scale, -g)
            except np.linalg.LinAlgError:
                delta = None
            if delta is not None:
                trial = p.copy()
                trial[free] += delta
                if bounded:
                    trial = np.clip(trial, lo, hi)
                r_trial = residuals(trial[None])[0]
                cost_trial = _cost(r_trial, huber)
                if cost_trial < cost:
                    break
            damping *= 10.0
            if damping > 1e16:  # no step lowers the cost: a minimum
                return p, r
        # The step as taken (clipped to the box when bounded).
        moved = trial - p if bounded else delta
        done = (
            np.linalg.norm(moved) <= tolerance * (np.linalg.norm(p) + tolerance)
            or cost - cost_trial <= tolerance * cost
        )
        if huber is None:
            damping = max(damping / 10.0, 1e-12)
        else:
            # Huber's loss bends where a residual crosses ``huber``: a step across that kink
            # lowers the cost by far less than the model said, and halving the damping after
            # it (as for squares) zig-zags across the kink in steps that barely lower it. The
            # damping follows how well the model predicted instead (Nielsen's rule).
            predicted = -(2.0 * g @ delta + delta @ A @ delta)
            ratio = (cost - cost_trial) / predicted if predicted > 0 else 0.0
            damping = max(damping * max(1.0 / 3.0, 1.0 - (2.0 * ratio - 1.0) ** 3), 1e-12)
        p, r, cost = trial, r_trial, cost_trial
        if done:
            break
    return p, r


def _cost(r: np.ndarray, huber: float | None) -> float:
    """The sum of squares, or Huber's loss scaled as one (equal to it within ``huber``)."""
    if huber is None:
        return float(r @ r)
    a = np.abs(r)
    return float(np.sum(np.where(a <= huber, a * a, huber * (2.0 * a - huber))))


def _huber_weights(r: np.ndarray, huber: float) -> np.ndarray:
    """The weight of each squared residual in a Gauss-Newton step of Huber's loss."""
    a = np.abs(r)
    return np.where(a <= huber, 1.0, huber / np.maximum(a, huber))
