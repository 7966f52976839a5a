"""Branch switching at a ``k``-fold resonance of a conservative family (``k >= 3``).

At an orbit of a conservative family whose section map has a multiplier pair
``exp(+-2 pi i m / k)`` (``gcd(m, k) = 1``), the ``k``-times iterated problem
(:meth:`~nsm_continuation.core.problem.Problem.iterated`: ``k`` returns to the section per
period) has the Jacobian ``G_y = [P^k_z - I, P^k_s]`` (``n x (n + 1)``) of rank ``n - 2``: its
kernel is three-dimensional, spanned by the family's tangent ``t1`` and the real and imaginary
parts ``(v_r, 0), (v_i, 0)`` of the pair's eigenvector (both fixed by ``D P^k``). Families of
period-``k`` orbits branch off in that plane: in the normal form of the ``k``-fold bifurcation
of a Hamiltonian family (Meyer, "Generic bifurcation of periodic points", Trans. AMS 149 (1970)
95-107) a period-``k`` orbit's ``k`` section points lie at radius ``r`` in the plane at angles
``phi* + 2 pi j / k``, with the parameter offset ``~ r`` for ``k = 3`` (one family through the
resonance, on both sides) and ``~ r^2`` for ``k >= 4``; ``phi*`` is set by the normal form's
coefficients, which are not computed here. Instead the plane is scanned: for each angle ``phi``
of :data:`ANGLES` (a half turn: ``phi + pi`` is the point of amplitude ``-eps``) and amplitude
``eps`` the corrector solves

    ``G(y) = 0``,   ``d_phi . (y - y_b) = eps``,   ``d_phi = cos(phi) e_1 + sin(phi) e_2``,

(``e_1, e_2`` an orthonormal basis of the kernel vectors without parameter component) from
``y_b + eps d_phi``; a solution is kept when it lies within ``10 eps`` of ``y_b`` and is no
orbit of the base family (``|G_base(y)| > 1e3 newton_tol (1 + |y|)``: a period-``k`` orbit
that is not ``k`` copies of one period). The first new solution is the start, and where the
amplitude ``-eps`` at the same angle gives another one on the other side of the resonance
(parameter offset of the other sign: ``k = 3``) that is a second start. Each start carries
``+-d_phi`` as its tangent: the run corrects it again on the row it was found with, and
continues it away from the resonance (along ``+-d_phi``).

**Weak resonances** (``k >= 4``). There the angular part of the normal form (order ``r^k``)
is no larger than its radial part, and the period-``k`` orbits are nearly degenerate along
their circle: at the 1/4 resonance of branch 1 at ``omega* = 1.5356441`` the bordered
Jacobian at the orbits has ``sigma_min / sigma_max = 5e-10`` at ``r = 0.076`` (``~ r^2``).
Newton from ``y_b + eps d_phi`` at an arbitrary angle wanders in that direction (residuals
between ``1e-14`` and ``1e-4`` over 12 iterations, condition ``1e-11``) and the scan finds
nothing. The start is then found on the reduced (Lyapunov-Schmidt) equation instead: both
plane coordinates are fixed, ``E (y - y_b) = r (cos phi, sin phi)``, and the residual along
the radial direction is unfolded by an unknown ``lam``,

    ``G(y) + lam w_phi = 0``,   ``w_phi``: ``d_phi`` in the residual's coordinates       (R2)

(the first rows of ``G`` are ``P^k(z) - z``), a regular system (condition ``~ 1e-3`` there):
its remaining plane equation, the rotation's detuning, is solved by moving along the family.
``lam(phi)`` is the bifurcation function: its zeros on a circle of :data:`REDUCED_ANGLES`
``k`` angles (closed by the Illinois iteration) are the period-``k`` orbits, whatever their
angle and side. Each zero is corrected once more on its own row (``d_phi . (y - y_b) = r``)
and kept when that converges (the problem's ``residual_floor``: the step there is the
residual's noise over the tiny singular value, ``1e-8`` at that resonance, never below
``newton_tol``) to an orbit off the base family; the amplitudes :data:`REDUCED_AMPLITUDES`
are tried in turn (``lam ~ r^(k-1)`` must stand above its noise).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from nsm_continuation.algorithms.base import TangentStart
from nsm_continuation.core.palc import NUMERICAL_ERRORS, ContinuationEngine, describe_error
from nsm_continuation.core.problem import Problem
from nsm_continuation.core.roots import illinois

#: amplitudes of the scan, times ``1 + |y_b|_inf``
AMPLITUDES = (3e-3, 1e-2)
#: angles of the scan in the kernel plane (a half turn; ``-eps`` covers the other half)
ANGLES = tuple(np.linspace(0.0, np.pi, 12, endpoint=False))
#: a kernel direction counts as singular below this ``sigma / sigma_max`` of ``G_y``
SINGULAR_RATIO = 1e-6
#: the kernel is three-dimensional where the next singular value is this many times the
#: second smallest (relative to each other, not to the largest: near the linear grazing orbit
#: the largest grows like ``1 / v`` with the impact velocity ``v``; at the 1/4 resonance
#: ``2e-3`` above it ``sigma_{n-2} = 2.6e-7`` of the largest, ``sigma_{n-1} = 1e-15``)
KERNEL_SEPARATION = 1e3
#: the lowest order whose start is found on the reduced equation (R2)
REDUCED_ORDER = 4
#: amplitudes of the reduced scan, times ``1 + |y_b|_inf``
REDUCED_AMPLITUDES = (1e-2, 3e-2, 1e-1)
#: angles of the reduced scan over a full turn, per order ``k`` (``lam`` has ``2 k`` zeros)
REDUCED_ANGLES = 4
#: Newton iterations of one solve of (R2)
REDUCED_ITERATIONS = 8


def resonance_plane(J: np.ndarray, ip: int) -> tuple[np.ndarray, float]:
    """``(E, gap)``: an orthonormal basis ``E`` (2 rows) of the kernel vectors of ``J``
    (``n x (n+1)``, the ``k``-times iterated problem at the resonance) without parameter
    component (index ``ip``), and ``sigma_{n-2} / sigma_max`` (the first non-zero singular
    value: how isolated the three-dimensional kernel is). Raises :class:`ValueError` where the
    kernel is not three-dimensional."""
    _, s, vt = np.linalg.svd(J)
    top = max(float(s[0]), 1.0)
    if s.size < 3 or float(s[-2]) / top > SINGULAR_RATIO:
        raise ValueError(f"the iterated problem's Jacobian has not a three-dimensional kernel "
                         f"there (singular values {s[-2] / top:.2g}, {s[-1] / top:.2g} of the "
                         "largest): no multiplier exp(2 pi i m / k)")
    gap = float(s[-3]) / top
    if float(s[-3]) < KERNEL_SEPARATION * float(s[-2]):
        raise ValueError(f"the iterated problem's kernel has dimension > 3 there (singular "
                         f"values {s[-3] / top:.2g}, {s[-2] / top:.2g} of the largest): two "
                         "resonances at once")
    K = vt[-3:]
    a = np.linalg.svd(K[:, ip][None, :])[2][1:]  # combinations without parameter component
    E = np.linalg.qr((a @ K).T)[0].T
    return E, gap


class _Switch:
    """The state of one switch: the iterated ``problem``, the base family's ``base``, the
    resonance ``yb``, its plane ``E``, an engine and the tally of failed tries."""

    def __init__(self, base: Problem, problem: Problem, yb: np.ndarray, E: np.ndarray,
                 settings: Any) -> None:
        self.base, self.problem, self.yb, self.E = base, problem, yb, E
        self.engine = ContinuationEngine(problem, settings)
        self.scale = 1.0 + float(np.linalg.norm(yb, np.inf))
        self.tol = float(settings.newton_tol)
        self.tried: dict[str, int] = {}

    def fail(self, why: str) -> None:
        key = why.split(" (")[0]
        self.tried[key] = self.tried.get(key, 0) + 1

    def direction(self, phi: float) -> np.ndarray:
        return np.cos(phi) * self.E[0] + np.sin(phi) * self.E[1]

    def accept(self, y: np.ndarray, eps: float) -> np.ndarray | None:
        """``y`` where it lies within ``10 eps`` of ``yb`` and is no orbit of the base
        family (module docstring)."""
        if float(np.linalg.norm(y - self.yb)) > 10.0 * abs(eps):
            self.fail("too far")
            return None
        try:
            g = float(np.linalg.norm(self.base.evaluate(y), np.inf))
        except NUMERICAL_ERRORS:
            g = np.inf
        if g <= 1e3 * self.tol * (1.0 + float(np.linalg.norm(y, np.inf))):
            self.fail("an orbit of the base family")
            return None
        return y

    def solve(self, d: np.ndarray, eps: float, y0: np.ndarray | None = None
              ) -> np.ndarray | None:
        """The corrector on ``d . (y - yb) = eps`` from ``y0`` (default ``yb + eps d``)."""
        guess = self.yb + eps * d if y0 is None else y0
        y, _, why = self.engine.correct(guess, d, self.yb, eps)
        if y is None:
            self.fail(why)
            return None
        return self.accept(y, eps)

    def scan(self, amplitudes: tuple[float, ...], angles: tuple[float, ...]
             ) -> tuple[list[tuple[np.ndarray, np.ndarray]], tuple[float, float] | None]:
        """The scan of the plane (module docstring): the starts and ``(eps, phi)``."""
        ip = self.problem.parameter_index
        for a in amplitudes:
            eps = a * self.scale
            for phi in angles:
                d = self.direction(phi)
                y = self.solve(d, eps)
                if y is None:
                    continue
                found = [(y, d)]
                y2 = self.solve(d, -eps)
                if y2 is not None and (y2[ip] - self.yb[ip]) * (y[ip] - self.yb[ip]) < 0:
                    found.append((y2, -d))
                return found, (eps, float(phi))
        return [], None

    def reduced(self, y0: np.ndarray, phi: float, r: float) -> tuple[float, np.ndarray | None]:
        """``(lam, y)``: Newton on (R2) at the angle ``phi``, radius ``r``, from ``y0``;
        ``(nan, None)`` where it fails."""
        pb, yb, E = self.problem, self.yb, self.E
        n = len(yb)
        d = self.direction(phi)
        y, lam = np.array(y0, dtype=float), 0.0
        for _ in range(REDUCED_ITERATIONS):
            try:
                g, A = pb.evaluate_with_jacobian(y)
            except NUMERICAL_ERRORS as exc:
                self.fail(describe_error(exc))
                return float("nan"), None
            self.engine.n_evaluations += 1
            w = d[: len(g)]
            M = np.zeros((len(g) + 2, n + 1))
            M[: len(g), :n], M[: len(g), n], M[len(g):, :n] = A, w, E
            rhs = np.concatenate([g + lam * w, E @ (y - yb) - r * np.array([np.cos(phi),
                                                                              np.sin(phi)])])
            try:
                dx = np.linalg.solve(M, -rhs)
            except np.linalg.LinAlgError:
                self.fail("singular reduced Jacobian")
                return float("nan"), None
            y, lam = y + dx[:n], lam + float(dx[n])
            if float(np.linalg.norm(dx, np.inf)) <= self.tol * self.scale:
                return lam, y
        self.fail("reduced equation did not converge")
        return float("nan"), None

    def reduced_scan(self, k: int, amplitudes: tuple[float, ...]
                     ) -> tuple[list[tuple[np.ndarray, np.ndarray]], tuple[float, float] | None]:
        """The zeros of the bifurcation function ``lam(phi)`` of (R2) on circles of the
        amplitudes, each corrected on its own row (module docstring): the first orbit of
        each sign of ``lam'`` (the two period-``k`` orbits) at the first amplitude that
        gives one, and ``(r, phi)`` of the first."""
        for a in amplitudes:
            r = a * self.scale
            phis = np.linspace(0.0, 2.0 * np.pi, REDUCED_ANGLES * k + 1)
            vals, ys, prev = [], [], self.yb + r * self.direction(0.0)
            for phi in phis:
                lam, y = self.reduced(prev, float(phi), r)
                vals.append(lam)
                ys.append(y)
                prev = y if y is not None else self.yb + r * self.direction(float(phi))
            found: dict[bool, tuple[np.ndarray, np.ndarray, float]] = {}
            for i in range(len(phis) - 1):
                if not vals[i] * vals[i + 1] < 0 or (vals[i] < 0) in found:
                    continue
                y0 = ys[i]

                def f(p: float, y0: np.ndarray = y0, r: float = r
                      ) -> tuple[float, np.ndarray | None]:
                    return self.reduced(y0, p, r)

                phi, y, _ = illinois(f, float(phis[i]), vals[i], float(phis[i + 1]),
                                     vals[i + 1], tol=1e-8, close=True)
                if y is None:
                    continue
                d = self.direction(phi)
                y = self.solve(d, r, y)
                if y is not None:
                    found[vals[i] < 0] = (y, d, phi)
            if found:
                starts = [(y, d) for y, d, _ in found.values()]
                return starts, (r, next(iter(found.values()))[2])
        return [], None


def resonance_starts(base: Problem, problem: Problem, yb: np.ndarray, settings: Any,
                     label: str = "", info: dict[str, Any] | None = None,
                     amplitudes: tuple[float, ...] = AMPLITUDES,
                     angles: tuple[float, ...] = ANGLES) -> tuple[list[TangentStart], dict]:
    """The first points of the period-``k`` family at the resonance ``yb`` of ``base`` (module
    docstring) as starts of ``problem`` (``base.iterated(k)``), and the switch's record: the
    scan of the plane for ``k < REDUCED_ORDER``, the reduced equation (R2) beyond.
    Raises :class:`ValueError` (no period-``k`` orbit found, with what each try gave)."""
    yb = np.asarray(yb, dtype=float)
    ip = problem.parameter_index
    k = int(problem.period_multiple())
    where = f"{problem.parameter} = {yb[ip]:.10g}"
    try:
        E, gap = resonance_plane(problem.jacobian(yb), ip)
    except NUMERICAL_ERRORS as exc:
        raise ValueError(f"switch at {where}: {describe_error(exc)}") from None
    except ValueError as exc:
        raise ValueError(f"switch at {where}: {exc}") from None
    sw = _Switch(base, problem, yb, E, settings)
    if k < REDUCED_ORDER:
        found, used = sw.scan(amplitudes, angles)
        method = "scan of the plane"
    else:
        found, used = sw.reduced_scan(k, REDUCED_AMPLITUDES)
        method = "zeros of the bifurcation function (R2)"
    if not found or used is None:
        what = "; ".join(f"{v} x {key}" for key, v in sw.tried.items())
        raise ValueError(f"switch at {where}: no period-{k} orbit found ({method}: {what})")
    rec = {**(info or {}), "switch_amplitude": used[0], "switch_angle": used[1],
           "switch_kernel_gap": gap, "switch_method": method, "period_multiple": k}
    starts = []
    for i, (y, d) in enumerate(found):
        if len(found) == 1:
            side = ""
        elif k < REDUCED_ORDER:
            side = " (above)" if y[ip] > yb[ip] else " (below)"
        else:
            side = f" (orbit {i + 1})"
        # the start is corrected again on the row it was found with (d . y fixed), and the
        # branch leaves along +d: away from the resonance
        starts.append(TangentStart(y, f"{label}{side}", 1, {**rec, "side": i}, tangent=d,
                                   forward_only=True))
    return starts, {"switch_residual_evaluations": sw.engine.n_evaluations}


__all__ = ["AMPLITUDES", "ANGLES", "REDUCED_AMPLITUDES", "REDUCED_ORDER", "resonance_plane",
           "resonance_starts"]
