"""Families of periodic orbits of a conservative impacting system, continued at fixed parameters.

A mechanical system ``M(q) qdd = f(q, qd)`` whose force is conservative (``f = -grad V`` plus the
velocity terms of a configuration-dependent ``M``) with elastic impacts (``e = 1`` on every
surface, :meth:`~.system.HybridSystem.mechanical`) conserves the energy
``E = qd^T M qd / 2 + V(q)``: its periodic orbits are not isolated at fixed parameters but come
in one-parameter families (the nonsmooth modes of Legrand, Junca, Heng 2017), along which the
period and the energy change. The section map ``P`` has the multiplier ``+1`` of the family
direction, ``P - I`` is singular along it, and shooting ``P(z) = z`` alone cannot be continued.

**Unfolding** (Munoz-Almaraz, Freire, Galan, Doedel, Vanderbauwhede, Physica D 181 (2003) 1-38;
AUTO-07p does the same in its demo ``r3b``, whose equations carry ``PAR(1) * (xp, yp, zp)`` and
whose runs free ``PAR(1)`` with the period ``PAR(11)``, ``ICP = [1, 11, ...]``):
:func:`unfold` adds a dissipative term of unknown size ``beta`` to the equations of motion,

    ``M(q) qdd = f(q, qd) + beta M(q) qd``,   i.e.   ``x' = F(x) + beta (0, qd)``       (U1)

along which ``dE/dt = beta qd^T M qd`` (the force's own terms cancel, ``f`` being conservative),
and an elastic impact conserves ``qd^T M qd`` (its impulse ``-2 M^-1 N (N^T qd) / (N^T M^-1 N)``
reflects ``qd`` in the metric ``M``). Over a periodic orbit of (U1) the energy returns to its
value, so ``0 = beta int_0^T qd^T M qd dt``: ``beta = 0`` on every periodic orbit that moves.
The unknowns of :class:`ConservativeShooting` are the section state ``z``, ``beta`` (lifted into
the state like any continuation parameter, :meth:`~.system.HybridSystem.compile`, so that its
Jacobian column ``P_beta`` is exact) and the continued quantity ``s``:

    ``G(z, beta) = P(z, beta) - z = 0``,   ``c(z, beta) - s = 0``                    (U2)

with ``c`` the return time (``s`` the period ``T``), ``2 pi / t`` (the frequency ``omega``) or
the energy ``E(x0(z))``. (U2) is regular along the family: ``P_z - I`` has the one-dimensional
kernel ``r`` (the family direction) and the left kernel ``l = grad E`` restricted to the section
(the map conserves ``E`` at ``beta = 0``); ``l . P_beta = dE/dbeta`` over one return ``=
int qd^T M qd dt > 0`` fills the missing rank, and the row of ``c`` makes the square system
nonsingular wherever ``dc/ds != 0`` along the family (a fold of the period, or an extremum of
the energy, is a fold of the branch in that quantity, not a singularity of the curve).

**The check.** ``beta`` is reported at every orbit; it vanishes to the accuracy of the
simulated map: a value ``|beta| T`` (the relative energy the unfolding would inject per period,
``Delta E / E ~ 2 beta <qd^T M qd / 2> T / E``) above :data:`UNFOLDING_TOL` times
``rtol + 10 eps`` means the system is not conservative (damping, a restitution below 1, a
non-conservative force) and ends the branch with that reason.

**Multipliers.** The section removes the flow's ``+1``; the section map's ``+1`` of the family
(right eigenvector ``r``: the ``z`` part of the branch tangent, ``dbeta/ds = 0``) is removed by
a Householder deflation (:func:`~nsm_continuation.core.floquet.deflate_known_eigenvector`), the
removal accurate to ``|lambda - 1| + |P r - lambda r| / |r|`` (``trivial_error``). The other
``n - 2`` multipliers (``n`` the state dimension) come in reciprocal pairs (the map restricted to
an energy level is symplectic). Their Krein definiteness (:func:`krein_definiteness`) comes from
the symplectic form ``omega = dq ^ dp`` (``p = M(q) qd``) of each eigenvector lifted to the full
state; the flow direction ``F`` is omega-orthogonal to the energy level (``omega(F, v) =
dE(v)``), so the form is the same on the section and on the quotient by the flow.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from nsm_continuation.core.floquet.norms import spectral_norm
from nsm_continuation.hybrid.return_map import (
    CrossingSection,
    SimulationCache,
    run_returns,
)
from nsm_continuation.hybrid.simulate import SimOptions, SimResult, Simulator
from nsm_continuation.hybrid.system import CompiledHybrid, HybridDeclarationError, HybridSystem

#: the name of the unfolding parameter (:func:`unfold`)
UNFOLDING = "beta"
#: the quantities a family is continued in (the last unknown of :class:`ConservativeShooting`)
QUANTITIES = ("period", "omega", "energy")
#: ``|beta| T`` above this times ``rtol + 10 eps`` (the simulated map's accuracy) is not zero:
#: the system is not conservative. Measured on the 5-dof chain: ``|beta| T <= 0.2 rtol`` for
#: ``rtol`` 1e-10 .. 1e-13 (500 times below the bound); a damping ``1e-10 K`` gives ``|beta| T =
#: 1.3e-9``, caught at ``rtol`` 1e-12
UNFOLDING_TOL = 1e2


def unfold(system: HybridSystem, name: str = UNFOLDING) -> HybridSystem:
    """The declaration of ``system`` with the unfolding term (U1): the parameter ``name`` and
    the field ``F + name (0, qd)`` (``M qdd = f + beta M qd``). ``system`` must be mechanical
    (``n_config`` positions followed by their velocities) and autonomous (no clock: the period
    of a forced system is fixed by its forcing). The impact law, the surfaces and the mass
    matrix are kept."""
    nq = system.n_config
    if nq is None or getattr(system, "_mass", None) is None:
        raise HybridDeclarationError(
            f"system {system.name!r}: the unfolding M qdd = f + beta M qd needs a mechanical "
            "declaration (HybridSystem.mechanical)")
    if system.clock_index is not None or system.n != 2 * nq:
        raise HybridDeclarationError(
            f"system {system.name!r}: a conservative family is autonomous (no clock): the "
            "period of a forced system is fixed by its forcing")
    if name in system.params:
        raise HybridDeclarationError(
            f"system {system.name!r}: the unfolding parameter {name!r} is already a parameter")
    beta = ca.SX.sym(name)
    params = {**system.params, name: beta}
    direction = ca.vertcat(ca.SX.zeros(nq), system.x[nq:2 * nq])
    out = HybridSystem(system.name, system.x, params, system.F + beta * direction, system.H,
                       system.W, list(system.state_names), dict(system.periodic),
                       position=list(system.position or []), n_config=nq,
                       surface_names=list(system.surface_names or []))
    qs = ca.SX.sym("q", nq)
    M = system._mass(qs, *system.params.values())  # type: ignore[attr-defined]
    out._mass = ca.Function("M", [qs, *params.values()], [M])  # type: ignore[attr-defined]
    out._nq = nq  # type: ignore[attr-defined]
    return out


def momentum_jacobian(system: HybridSystem) -> ca.Function:
    """``d(q, p)/dx`` with ``p = M(q) qd``, as a Function of the state and the parameters (in
    the order of ``system.params``): the coordinates of the symplectic form ``dq ^ dp``."""
    nq = system.n_config or 0
    x = system.x
    q, qd = x[:nq], x[nq:2 * nq]
    p = ca.mtimes(system._mass(q, *system.params.values()), qd)  # type: ignore[attr-defined]
    return ca.Function("dqp", [x, *system.params.values()],
                       [ca.jacobian(ca.vertcat(q, p), x)])


def krein_definiteness(vectors: np.ndarray, dqp: np.ndarray) -> np.ndarray:
    """Krein definiteness of each column of ``vectors`` (perturbations of the full state):
    ``kappa = g / |w|^2`` with ``g = -i omega(conj w, w) = 2 Im(conj(dq) . dp)`` and
    ``|w|^2 = |dq|^2 + |dp|^2`` (``(dq, dp) = dqp w``), so ``|kappa| <= 1``; on the unit circle
    its sign is the Krein signature (the convention of
    :class:`~nsm_continuation.core.floquet.KreinFloquetData`: for the chain ``dq ^ dp`` is the
    form ``sum_j d xi_j ^ d eta_j / w_j`` of its energy coordinates)."""
    W = dqp @ vectors
    nq = W.shape[0] // 2
    dq, dp = W[:nq], W[nq:]
    g = 2.0 * np.sum(np.conj(dq) * dp, axis=0).imag
    norm = np.sum(np.abs(dq) ** 2 + np.abs(dp) ** 2, axis=0)
    return np.where(norm > 0, g / np.where(norm > 0, norm, 1.0), 0.0)


class ConservativeShooting:
    """The unfolded shooting problem (U2) of a compiled, unfolded system (``c.free`` is
    ``[beta]``) on a :class:`CrossingSection`.

    Unknowns ``y = (z, beta, s)``: ``z`` the section state without its fixed component,
    ``beta`` the unfolding, ``s`` the continued ``quantity`` (``period``, ``omega`` or
    ``energy``; ``energy`` needs the Function ``energy(X)``). Residual ``[P(z, beta) - z;
    c(z, beta) - s]`` with the exact Jacobian ``[[P_z - I, P_beta, 0], [c_z, c_beta, -1]]``
    (``c_z = J_t / m`` for the period ``t / m``, the frequency written ``t - 2 pi m / omega``:
    row ``J_t``, column ``2 pi m / omega^2``, ``grad E`` for the energy; ``m`` = ``multiple``,
    1 but for a period-``2k`` family, whose period and frequency are its base period's, so
    that it starts at the period doubling's values). One simulation per ``(z, beta)``
    (cached: the same orbit at another ``s`` is not simulated again)."""

    def __init__(self, c: CompiledHybrid, section: CrossingSection, opts: SimOptions,
                 quantity: str, energy: ca.Function | None = None, cache_size: int = 16,
                 multiple: int = 1) -> None:
        if c.free != [UNFOLDING]:
            raise ValueError(f"the unfolded system is compiled with free = [{UNFOLDING!r}] "
                             f"(got {c.free})")
        if quantity not in QUANTITIES or (quantity == "energy" and energy is None):
            raise ValueError(f"continuation.parameter: {quantity!r} is not a quantity of this "
                             f"family (one of {self.quantities(energy is not None)})")
        self.c = c
        self.section = section
        self.sim = Simulator(c, opts)
        self.quantity = quantity
        self.energy = energy
        #: the orbits are ``multiple`` periods of a base family (a period-``2k`` family born
        #: at a period doubling): the period and the frequency are the base period's
        self.multiple = int(multiple)
        self.free_idx = [i for i in range(c.n) if i != section.index]
        self._cache = SimulationCache(cache_size)

    @staticmethod
    def quantities(has_energy: bool) -> list[str]:
        """The quantities a family can be continued in."""
        return [q for q in QUANTITIES if has_energy or q != "energy"]

    @staticmethod
    def shooting_unknowns(y: np.ndarray) -> np.ndarray:
        """``(z, beta)``: ``y`` without the continued quantity."""
        return np.asarray(y, dtype=float)[:-1]

    def x0(self, y: np.ndarray) -> np.ndarray:
        """The state on the section with ``beta`` (length ``N = n + 1``) from ``y`` (with or
        without its last entry, the continued quantity)."""
        c = self.c
        y = np.asarray(y, dtype=float)
        X = np.empty(c.N)
        X[self.free_idx] = y[: c.n - 1]
        X[self.section.index] = self.section.value
        X[c.n] = y[c.n - 1]
        return X

    def _run(self, X0: np.ndarray) -> SimResult:
        """``returns`` crossings of the section from ``X0``, chained
        (:func:`~.return_map.run_returns`)."""
        return run_returns(self.sim, X0, self.section)

    def simulate(self, y: np.ndarray) -> SimResult:
        """The simulated period from ``y`` (``(z, beta)`` or ``(z, beta, s)``), cached;
        :class:`~.return_map.ShootingFailure` with the simulator's reason."""
        yy = np.asarray(y, dtype=float)[: self.c.n]
        return self._cache.get(yy, lambda: self._run(self.x0(yy)))

    def energy_gradient(self, y: np.ndarray) -> tuple[float, np.ndarray]:
        """``E`` and ``grad E`` at the section state of ``y`` (``energy`` declared)."""
        assert self.energy is not None
        E, dE = self.energy(self.x0(y))
        return float(E), np.asarray(dE, dtype=float).ravel()

    def residual_jacobian(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``[G; c - s]`` and its Jacobian (U2)."""
        c = self.c
        y = np.asarray(y, dtype=float)
        res = self.simulate(y)
        X0 = self.x0(y)
        fi = self.free_idx
        m = len(fi)
        cols = fi + [c.n]
        A = np.zeros((m + 1, m + 2))
        A[:m, : m + 1] = res.J[np.ix_(fi, cols)]
        A[:m, :m] -= np.eye(m)
        g = res.X[fi] - X0[fi]
        s = float(y[-1])
        k = float(self.multiple)
        if self.quantity == "energy":
            E, dE = self.energy_gradient(y)
            A[m, : m + 1] = dE[cols]
            A[m, m + 1] = -1.0
            r = E - s
        elif self.quantity == "period":
            A[m, : m + 1] = res.Jt[cols] / k
            A[m, m + 1] = -1.0
            r = res.t / k - s
        else:
            A[m, : m + 1] = res.Jt[cols]
            A[m, m + 1] = 2.0 * np.pi * k / s ** 2
            r = res.t - 2.0 * np.pi * k / s
        return np.append(g, r), A

    def quantity_value(self, y: np.ndarray) -> float:
        """The continued quantity of the orbit through ``y`` (its ``c(z, beta)``)."""
        if self.quantity == "energy":
            return self.energy_gradient(y)[0]
        t = float(self.simulate(y).t) / self.multiple
        return t if self.quantity == "period" else 2.0 * np.pi / t

    def poincare_jacobian(self, y: np.ndarray) -> np.ndarray:
        """``P_z`` (the section map's Jacobian in the section coordinates)."""
        res = self.simulate(y)
        fi = self.free_idx
        return res.J[np.ix_(fi, fi)]

    def _monodromy(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(Phi_T, F(x0), F(x_T))``: the time-fixed monodromy ``P_x - F(x_T) J_t``."""
        c = self.c
        res = self.simulate(y)
        n = c.n
        F0 = np.asarray(c.f(self.x0(y)), dtype=float).ravel()[:n]
        FT = np.asarray(c.f(res.X), dtype=float).ravel()[:n]
        return res.J[:n, :n] - np.outer(FT, res.Jt[:n]), F0, FT

    def trivial_error(self, y: np.ndarray) -> float:
        """The flow's trivial multiplier, as a check: ``|Phi_T F(x0) - F(x_T)| / |F|``."""
        Phi, F0, FT = self._monodromy(y)
        return float(np.linalg.norm(Phi @ F0 - FT) / max(np.linalg.norm(F0), 1e-300))

    def monodromy_noise(self, y: np.ndarray) -> float:
        """Absolute accuracy of ``P_z``: ``(rtol + 10 eps) |Phi_T|_2``
        (:meth:`~.return_map.HybridShooting.monodromy_noise`)."""
        Phi, _, _ = self._monodromy(y)
        return float((self.sim.o.rtol + 10.0 * np.finfo(float).eps) * spectral_norm(Phi))

    def lift(self, w: np.ndarray) -> np.ndarray:
        """Section perturbations (columns of ``w``) as perturbations of the full state (zero
        along the section coordinate)."""
        out = np.zeros((self.c.n, w.shape[1]), dtype=w.dtype)
        out[self.free_idx] = w
        return out
