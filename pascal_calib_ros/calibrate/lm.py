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


def levenberg_marquardt(prob: LeastSquaresProblem, x0: np.ndarray, intr0: np.ndarray, loss_scale: float,
                        max_iter: int = 60, tol: float = 1e-10) -> LMResult:
    """Levenberg-Marquardt with iteratively reweighted soft-L1 loss rho(z) = 2 (sqrt(1 + z) - 1),
    z = (r / f)^2, weights 1 / sqrt(1 + z); normal equations from :meth:`Problem.normal_equations`
    (Jacobi-scaled, dense: a few hundred parameters at most). A trial step's residuals are
    evaluated without the Jacobian; it is assembled only for the steps taken."""
    x = x0.copy()
    f, Jg, Jv = prob.evaluate(x, intr0)
    nfev = 1

    def robust_cost(r: np.ndarray) -> float:
        return prob.robust_cost(r, loss_scale)

    cost = robust_cost(f)
    lam = 1e-3
    message, success = "maximum iterations reached", False
    it = 0
    for it in range(1, max_iter + 1):  # noqa: B007 (the count is reported)
        w = prob.robust_weights(f, loss_scale)
        A, g = prob.normal_equations(f, Jg, Jv, w)
        d = np.sqrt(np.maximum(np.diag(A), 1e-30))
        An = A / d[:, None] / d[None, :]
        gn = g / d
        improved = False
        for _ in range(12):
            try:
                step = -np.linalg.solve(An + lam * np.eye(len(x)), gn) / d
            except np.linalg.LinAlgError:
                lam *= 10
                continue
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
            lam *= 10
        if not improved:
            message, success = "no further decrease of the cost", True
            break
        if rel < tol or np.linalg.norm(step * d) < tol * (np.linalg.norm(x * d) + tol):
            message, success = "converged", True
            break
    w = prob.robust_weights(f, loss_scale)
    A, _ = prob.normal_equations(f, Jg, Jv, w)
    return LMResult(x=x, fun=f, normal_matrix=A, weights=w, cost=cost, nfev=nfev, iterations=it, success=success,
                    message=message, jacobian=(Jg, Jv))
