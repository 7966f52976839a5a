"""Equilibria on the sticking surface and their eigenvalues (sec. 6.3, eqs. (60)-(61)).

An equilibrium of the sticking field ``F'`` (eq. 10) on the impact surface solves
``F'(x) = 0, H(x) = 0``; for a mechanical system this is ``V(q) = lambda N(q)``, ``H(q) = 0``
with ``qd = 0`` (eqs. 60-61). Its eigenvalues are those of ``F'_x`` (exact, CasADi) at the
point: two of them belong to the constraint directions (``H`` and ``v``; ``F'`` keeps ``v``
exactly and moves ``H`` at rate ``v``: a nilpotent 2x2 block, eigenvalues 0, 0) and are
removed; the others are the equilibrium's own (a saddle: one positive, one negative for the
pendulum). The guess is a point of an orbit's sticking phase (e.g. where chattering completes).
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from nsm_continuation.hybrid.system import CompiledHybrid


def sticking_equilibrium(c: CompiledHybrid, guess: np.ndarray, tol: float = 1e-13,
                         max_iter: int = 60) -> dict[str, Any]:
    """Gauss-Newton on ``[F'(x); H(x)] = 0`` from ``guess`` (state followed by the freed
    parameters, which stay fixed). Returns the state, ``lambda``, the nontrivial eigenvalues,
    the residual and whether it converged."""
    n, N = c.n, c.N
    X = ca.SX.sym("X", N)
    Fs = c.fs(X)[:n]
    H = c.probe(X)[0]
    G = ca.vertcat(Fs, H)
    fun = ca.Function("eq", [X], [G, ca.jacobian(G, X)[:, :n], ca.jacobian(Fs, X)[:, :n]])
    x = np.asarray(guess, dtype=float).copy()
    ok = False
    res = np.inf
    for _ in range(max_iter):
        g, Jg, _ = (np.asarray(v, dtype=float) for v in fun(x))
        g = g.ravel()
        res = float(np.linalg.norm(g, np.inf))
        if res <= tol * (1.0 + np.linalg.norm(x[:n], np.inf)):
            ok = True
            break
        dx = np.linalg.lstsq(Jg, -g, rcond=None)[0]
        x[:n] += dx
        if not np.all(np.isfinite(x)):
            break
    _, _, A = (np.asarray(v, dtype=float) for v in fun(x))
    ev = np.linalg.eigvals(A[:n, :n])
    scale = max(float(np.max(np.abs(ev))), 1e-300)
    nontrivial = np.sort_complex(ev[np.abs(ev) > 1e-6 * scale])
    q = c.q(x)
    return {"x": x[:n].tolist(), "lambda": q["lam"], "eigenvalues": nontrivial,
            "all_eigenvalues": ev, "residual": res, "converged": ok,
            "saddle": bool(np.any(nontrivial.real > 0) and np.any(nontrivial.real < 0))}
