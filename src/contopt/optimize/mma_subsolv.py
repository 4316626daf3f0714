"""The MMA subproblem and its primal-dual interior point solver (Svanberg 2007, section 5).

:class:`Subproblem` is the convex separable approximation that :func:`contopt.optimize.mma.mmasub`
builds at an iterate; :func:`subsolv` solves it. :class:`PrimalDual` is a point of the subproblem
(or of the augmented problem, for the KKT check of :mod:`contopt.optimize.mma`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

EPSIMIN = 1e-7  # smallest barrier parameter
MAX_NEWTON = 200  # Newton steps per barrier parameter
MAX_HALVINGS = 50  # step halvings per Newton step


@dataclass(frozen=True, eq=False)
class Subproblem:
    """The convex separable MMA approximation at one iterate (n variables, m constraints).

    low, upp : (n,) asymptotes; alfa, beta : (n,) bounds of x (box and move limits)
    p0, q0 : (n,) objective terms ``sum_j p0_j/(upp_j - x_j) + q0_j/(x_j - low_j)``
    P, Q : (m, n) the same for the constraints, which read
        ``sum_j P_ij/(upp_j - x_j) + Q_ij/(x_j - low_j) - a_i z - y_i <= b_i``
    b : (m,) right-hand sides
    a0 : float; a, c, d : (m,) constants of the augmented problem
    """

    low: np.ndarray
    upp: np.ndarray
    alfa: np.ndarray
    beta: np.ndarray
    p0: np.ndarray
    q0: np.ndarray
    P: np.ndarray
    Q: np.ndarray
    b: np.ndarray
    a0: float
    a: np.ndarray
    c: np.ndarray
    d: np.ndarray


@dataclass(frozen=True, eq=False)
class PrimalDual:
    """A primal-dual point of the subproblem (or of the augmented problem).

    x : (n,); y : (m,); z : float (primal)
    lam : (m,) constraint multipliers; xsi, eta : (n,) multipliers of x >= alfa
    and x <= beta; mu : (m,) of y >= 0; zet : float of z >= 0; s : (m,) slacks
    """

    x: np.ndarray
    y: np.ndarray
    z: float
    lam: np.ndarray
    xsi: np.ndarray
    eta: np.ndarray
    mu: np.ndarray
    zet: float
    s: np.ndarray

    def moved(self, step: PrimalDual, t: float) -> PrimalDual:
        """``self + t * step``, field by field."""
        return PrimalDual(*(getattr(self, f.name) + t * getattr(step, f.name) for f in dataclasses.fields(self)))


def subsolv(sub: Subproblem) -> tuple[PrimalDual, int]:
    """Solve the MMA subproblem by a primal-dual Newton method on its relaxed KKT conditions.

    The complementarity products are set to a barrier parameter epsi = 1, 0.1,
    ... down to EPSIMIN; at each level Newton steps (with step halving on the
    residual norm) run until the largest residual is below 0.9 epsi. Returns the
    solution and the total number of Newton steps.
    """
    w = _initial_point(sub)
    epsi = 1.0
    total = 0
    while epsi > EPSIMIN:
        w, steps = _newton_at_level(w, sub, epsi)
        total += steps
        epsi *= 0.1
    return w, total


def _initial_point(sub: Subproblem) -> PrimalDual:
    """Svanberg's interior starting point: x mid-way between alfa and beta, the rest 1 or more."""
    m = sub.b.shape[0]
    x = 0.5 * (sub.alfa + sub.beta)
    ones = np.ones(m)
    return PrimalDual(
        x=x,
        y=ones.copy(),
        z=1.0,
        lam=ones.copy(),
        xsi=np.maximum(1.0 / (x - sub.alfa), 1.0),
        eta=np.maximum(1.0 / (sub.beta - x), 1.0),
        mu=np.maximum(1.0, 0.5 * sub.c),
        zet=1.0,
        s=ones.copy(),
    )


def _newton_at_level(w: PrimalDual, sub: Subproblem, epsi: float) -> tuple[PrimalDual, int]:
    """Newton steps on the KKT residual with barrier ``epsi``; returns the point and the step count."""
    r = sub_residual(w, sub, epsi)
    norm, largest = np.linalg.norm(r), np.max(np.abs(r))
    steps = 0
    while largest > 0.9 * epsi and steps < MAX_NEWTON:
        steps += 1
        dw = newton_direction(w, sub, epsi)
        t = _max_step(w, dw, sub)
        # halve until the residual norm does not grow; the last trial is taken regardless
        for _ in range(MAX_HALVINGS):
            trial = w.moved(dw, t)
            r = sub_residual(trial, sub, epsi)
            if np.linalg.norm(r) <= norm:
                break
            t *= 0.5
        w = trial
        norm, largest = np.linalg.norm(r), np.max(np.abs(r))
    return w, steps


def sub_residual(w: PrimalDual, sub: Subproblem, epsi: float) -> np.ndarray:
    """Residual (3n + 4m + 2,) of the subproblem's KKT conditions with complementarity = ``epsi``."""
    ux = sub.upp - w.x
    xl = w.x - sub.low
    plam = sub.p0 + sub.P.T @ w.lam
    qlam = sub.q0 + sub.Q.T @ w.lam
    gvec = sub.P @ (1.0 / ux) + sub.Q @ (1.0 / xl)
    return np.concatenate(
        [
            plam / ux**2 - qlam / xl**2 - w.xsi + w.eta,
            sub.c + sub.d * w.y - w.mu - w.lam,
            [sub.a0 - w.zet - sub.a @ w.lam],
            gvec - sub.a * w.z - w.y + w.s - sub.b,
            w.xsi * (w.x - sub.alfa) - epsi,
            w.eta * (sub.beta - w.x) - epsi,
            w.mu * w.y - epsi,
            [w.zet * w.z - epsi],
            w.lam * w.s - epsi,
        ]
    )


def newton_direction(w: PrimalDual, sub: Subproblem, epsi: float) -> PrimalDual:
    """Newton direction of the relaxed KKT system, reduced to an (m+1) or (n+1) square system.

    The multipliers xsi, eta, mu, zet and the slacks s are eliminated through
    their complementarity equations, then y; what is left couples (lam, z)
    (when m < n) or (x, z) (otherwise), whichever is smaller.
    """
    m, n = sub.P.shape
    ux = sub.upp - w.x
    xl = w.x - sub.low
    xa = w.x - sub.alfa
    bx = sub.beta - w.x
    plam = sub.p0 + sub.P.T @ w.lam
    qlam = sub.q0 + sub.Q.T @ w.lam
    gvec = sub.P @ (1.0 / ux) + sub.Q @ (1.0 / xl)
    G = sub.P / ux**2 - sub.Q / xl**2  # (m, n) constraint gradients of the approximation

    delx = plam / ux**2 - qlam / xl**2 - epsi / xa + epsi / bx
    dely = sub.c + sub.d * w.y - w.lam - epsi / w.y
    delz = sub.a0 - sub.a @ w.lam - epsi / w.z
    dellam = gvec - sub.a * w.z - w.y - sub.b + epsi / w.lam
    diagx = 2.0 * (plam / ux**3 + qlam / xl**3) + w.xsi / xa + w.eta / bx
    diagy = sub.d + w.mu / w.y
    diaglamyi = w.s / w.lam + 1.0 / diagy
    rhs_lam = dellam + dely / diagy

    if m < n:
        A = np.empty((m + 1, m + 1))
        A[:m, :m] = (G / diagx) @ G.T + np.diag(diaglamyi)
        A[:m, m] = sub.a
        A[m, :m] = sub.a
        A[m, m] = -w.zet / w.z
        rhs = np.concatenate([rhs_lam - G @ (delx / diagx), [delz]])
        sol = np.linalg.solve(A, rhs)
        dlam, dz = sol[:m], float(sol[m])
        dx = -(delx + G.T @ dlam) / diagx
    else:
        A = np.empty((n + 1, n + 1))
        axz = -G.T @ (sub.a / diaglamyi)
        A[:n, :n] = G.T @ (G / diaglamyi[:, None]) + np.diag(diagx)
        A[:n, n] = axz
        A[n, :n] = axz
        A[n, n] = w.zet / w.z + sub.a @ (sub.a / diaglamyi)
        rhs = -np.concatenate([delx + G.T @ (rhs_lam / diaglamyi), [delz - sub.a @ (rhs_lam / diaglamyi)]])
        sol = np.linalg.solve(A, rhs)
        dx, dz = sol[:n], float(sol[n])
        dlam = (rhs_lam + G @ dx - sub.a * dz) / diaglamyi

    dy = (dlam - dely) / diagy
    return PrimalDual(
        x=dx,
        y=dy,
        z=dz,
        lam=dlam,
        xsi=-w.xsi + epsi / xa - w.xsi * dx / xa,
        eta=-w.eta + epsi / bx + w.eta * dx / bx,
        mu=-w.mu + epsi / w.y - w.mu * dy / w.y,
        zet=-w.zet + epsi / w.z - w.zet * dz / w.z,
        s=-w.s + epsi / w.lam - w.s * dlam / w.lam,
    )


def _max_step(w: PrimalDual, dw: PrimalDual, sub: Subproblem) -> float:
    """Largest step <= 1 keeping x strictly inside (alfa, beta) and the other variables positive.

    The factor 1.01 keeps a 1% margin from the boundary, as in Svanberg's code.
    """
    ratios = np.concatenate(
        [
            -dw.x / (w.x - sub.alfa),
            dw.x / (sub.beta - w.x),
            -dw.y / w.y,
            [-dw.z / w.z],
            -dw.lam / w.lam,
            -dw.xsi / w.xsi,
            -dw.eta / w.eta,
            -dw.mu / w.mu,
            [-dw.zet / w.zet],
            -dw.s / w.s,
        ]
    )
    return 1.0 / max(1.0, 1.01 * float(np.max(ratios)))
