"""Levenberg-Marquardt with iteratively reweighted robust loss on a :class:`~.problem.Problem`
(Nocedal & Wright, "Numerical Optimization", 2006, sec. 10.3; Jacobi scaling of the normal equations)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np


class LeastSquaresProblem(Protocol):
    """What :func:`levenberg_marquardt` and the sandwich covariance need of a problem:
    :class:`~.problem.Problem`, :class:`~.handeye.chain.ChainProblem`, :class:`~.rig_problem.RigProblem`."""

    def evaluate(self, x: np.ndarray, intr0: np.ndarray, jac: bool = True
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...

    def robust_weights(self, f: np.ndarray, loss_scale: float) -> np.ndarray: ...

    def robust_cost(self, f: np.ndarray, loss_scale: float) -> float: ...

    def loss_derivatives(self, f: np.ndarray, loss_scale: float) -> tuple[np.ndarray, np.ndarray]: ...

    def normal_equations(self, f: np.ndarray, Jg: np.ndarray, Jv: np.ndarray, w: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray]: ...


@dataclass
class LMResult:
    x: np.ndarray
    fun: np.ndarray
    normal_matrix: np.ndarray  # J^T W J at the solution
    weights: np.ndarray
    cost: float
    nfev: int
    iterations: int
    success: bool
    message: str
    jacobian: tuple[np.ndarray, np.ndarray] | None = None  # (dF/d globals, dF/d own view) at the solution


@dataclass(frozen=True)
class LMOptions:
    """How :func:`levenberg_marquardt` steps and stops. The default is the calibration's own; a start
    already near the solution (a warm start) converges in fewer steps with :data:`WARM_START`: little
    damping at first, the normal matrix weighted by w^p (p = 1: IRLS, J^T W J; p = 3: Newton's for
    the soft-L1 loss, rho'' = w^3), and a stop once a step's predicted decrease of the cost,
    -(g^T s + s^T A s / 2), is below ``min_predicted`` times the cost, or once a step that failed was
    predicted to gain less than ``stall_predicted`` times it (the edge rows' Jacobian is exact only at
    the foot point: within that, a step may not decrease the cost). The fixed point, J^T W f = 0, is
    the same for every choice."""

    lam0: float = 1e-3
    hessian_power: int = 1
    min_predicted: float = 0.0
    stall_predicted: float = 0.0


DEFAULT_LM = LMOptions()
WARM_START = LMOptions(lam0=1e-9, hessian_power=1, min_predicted=1e-12, stall_predicted=1e-7)


def levenberg_marquardt(prob: LeastSquaresProblem, x0: np.ndarray, intr0: np.ndarray, loss_scale: float,
                        max_iter: int = 60, tol: float = 1e-10, options: LMOptions = DEFAULT_LM) -> LMResult:
    """Levenberg-Marquardt with iteratively reweighted soft-L1 loss rho(z) = 2 (sqrt(1 + z) - 1),
    z = (r / f)^2, weights 1 / sqrt(1 + z); normal equations from :meth:`Problem.normal_equations`
    (Jacobi-scaled, dense: a few hundred parameters at most). A trial step's residuals are
    evaluated without the Jacobian; it is assembled only for the steps taken. ``options``:
    :class:`LMOptions`."""
    x = x0.copy()
    f, Jg, Jv = prob.evaluate(x, intr0)
    nfev = 1

    def robust_cost(r: np.ndarray) -> float:
        return prob.robust_cost(r, loss_scale)

    cost = robust_cost(f)
    lam = options.lam0
    message, success = "maximum iterations reached", False
    it = 0
    for it in range(1, max_iter + 1):  # noqa: B007 (the count is reported)
        w = prob.robust_weights(f, loss_scale)
        p = options.hessian_power
        # J^T diag(w^p) J and, with f w^(1-p), the gradient J^T W f from one assembly
        A, g = prob.normal_equations(f, Jg, Jv, w) if p == 1 else prob.normal_equations(f * w ** (1 - p), Jg, Jv,
                                                                                        w**p)
        d = np.sqrt(np.maximum(np.diag(A), 1e-30))
        An = A / d[:, None] / d[None, :]
        gn = g / d
        improved = predicted_small = False
        for _ in range(12):
            try:
                sn = -np.linalg.solve(An + lam * np.eye(len(x)), gn)
            except np.linalg.LinAlgError:
                lam *= 10
                continue
            predicted = -(gn @ sn + 0.5 * sn @ An @ sn) if options.min_predicted > 0 else np.inf
            if predicted < options.min_predicted * cost:
                predicted_small = True
                break
            step = sn / d
            xn = x + step
            fn = prob.evaluate(xn, intr0, jac=False)[0]
            nfev += 1
            cn = robust_cost(fn)
            if cn < cost:
                rel = (cost - cn) / max(cost, 1e-300)
                x, f, cost = xn, fn, cn
                _, Jg, Jv = prob.evaluate(x, intr0)
                lam = max(lam * 0.2, 1e-9)
                improved = True
                break
            if predicted < options.stall_predicted * cost:
                predicted_small = True
                break
            lam *= 10
        if not improved:
            message, success = "converged" if predicted_small else "no further decrease of the cost", True
            break
        if rel < tol or np.linalg.norm(step * d) < tol * (np.linalg.norm(x * d) + tol):
            message, success = "converged", True
            break
    w = prob.robust_weights(f, loss_scale)
    A, _ = prob.normal_equations(f, Jg, Jv, w)
    return LMResult(x=x, fun=f, normal_matrix=A, weights=w, cost=cost, nfev=nfev, iterations=it, success=success,
                    message=message, jacobian=(Jg, Jv))
