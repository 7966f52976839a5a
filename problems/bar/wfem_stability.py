"""Orbital stability of the WFEM bar's nonsmooth modes (Yoong, Thorin, Legrand 2017).

The paper leaves the stability of the bar's periodic orbits open. Spectral (Floquet) stability is
empty here: with grid-aligned switching the linearisation of a lattice orbit is the signed
permutation ``A_c^p A_f^m`` (:mod:`problems.bar.wfem_operators`), whose eigenvalues all lie on the
unit circle, and a perturbation too small to move a switching instant by one step is transported
exactly linearly (no growth, no decay). This module measures stability *directly*: perturbations
resolved by the grid (they move switching instants by several steps) are time stepped with the
floating boundary condition (Algorithm 2 of the paper, on the characteristic ring), and their
distance to the unperturbed orbit *as a set* is followed period after period.

Method
------
* Time stepping: :func:`floating_bc_simulation`, Algorithm 2 on the ring, O(1) per step (a moving
  origin on the ring buffer; about 0.4 s per 10^6 steps here). The end displacement ``u_end`` is the
  time integral of the end velocity, started from the state (``u_end = dx/(2E) sum w``, exact for
  the clamped bar) and never reset, so it stays the displacement of the state (resetting it to
  ``g0`` at each closure, as a shortcut, would discard the closure overshoot, always of the same
  sign, and shift the effective gap by up to one step per period). A step is CONTACT when
  ``g0 - u_end <= 0`` (up to a tolerance) and the arriving characteristic is compressive,
  ``J = w[N-1] <= 0``, FREE otherwise, decided at its beginning by the switching rule shared
  with :func:`problems.bar.wfem_stepping.simulate`
  (:func:`problems.bar.wfem_operators.floating_bc_contact`).
* Perturbations (:func:`perturbation_growth`, :func:`perturb`), all admissible (no penetration):

  - ``"delay"``: the release (contact -> free) is delayed by ``j = round(eps N)`` steps, i.e. the
    end is held on the obstacle for j steps while the arriving wave is tensile. A switching-time
    perturbation resolved by the grid: it leaves a thin pulse (width j slots, height 2A) in the
    outgoing wave, which a switching-time error always leaves unless something cancels it, and
    keeps ``u_end = g0``; energy and ``|w_k|`` unchanged;
  - ``"shift"``: in the middle of the contact phase (where the mode-1 profile has two interior
    jumps; in the free phase it has one and moving it is a mere phase shift), one jump of the
    ``+-A`` profile moved by ``j = round(eps N)`` slots, in the direction that opens a gap:
    energy-preserving, the end then flies free for about 2j steps (a micro-impact);
  - ``"smooth"``: ``eps * A * phi`` added in the middle of the contact phase, ``phi`` a random
    trigonometric polynomial of the ring coordinate (harmonics 0..6, weights 1/(q+1),
    ``max |phi| = 1``), with the sign that opens the gap: changes the energy, the values ``|w_k|``
    and the switching instants (by O(eps N) steps);
  - ``"scale"``: ``w -> (1 - eps) w`` in the middle of the contact phase (towards a neighbouring
    member of the family).
* Distances (:func:`orbital_distance`): ``d(w) = min_k |w - W_k| / |W|`` over the M states ``W_k``
  of the unperturbed orbit (phase drift is not counted), in the L1 norm of the characteristic
  profile or the energy norm (Euclidean norm of ``w``: the energy is ``dx |w|^2 / (4E)``, so
  ``d^2`` is the energy of the difference relative to the orbit's). The *distance to the family*
  (:func:`family_distance`) is the orbital distance to the member of the continuum branch with the
  *same energy* (cell averages of its profile at half-step phases,
  :mod:`problems.bar.continuum_orbits`): the energy is exactly conserved, so that member is the
  only one of the family a perturbed trajectory could approach in the energy norm.
* Classification (:func:`classify_growth`, :data:`GROWTH_CRITERION`): bounded (the running
  maximum of the distance stays within 5x the initial one, the grid resolution as a floor) /
  linear growth / exponential growth (fits of the rising part); a growth verdict needs a small
  initial perturbation, and linear vs exponential is also decided by the size scaling (the time
  to reach a given distance ~ 1/size for linear growth, ~ log(1/size) for exponential).

Exact invariants (tested)
-------------------------
Every step is a signed permutation of the ring, whatever the switching decision, so the *multiset*
``{|w_k|}`` is invariant: all the norms ``sum |w_k|^p`` are conserved, not only the energy.

1. The energy-norm orbital distance is bounded by ``1 + |w_0|/|W| <= 2 + eps`` forever: there is
   no exponential (or unbounded) growth in the energy norm, nor in any L^p norm.
2. A trajectory can approach a family member only if all its ``|w_k|`` equal that member's
   amplitude: a perturbation making ``|w|`` non-constant can never decay. No orbit is
   asymptotically stable; the question is Lyapunov (orbital) stability.
3. The distance can change only through the *signs* of ``w``, i.e. the positions of the jumps of
   the ``+-A`` profile, which is where the switching instants enter. For ``+-A`` states differing
   by sign changes only, ``d_energy^2 = 2 d_L1``: a displaced jump costs L1 distance
   proportional to its displacement but energy-norm distance proportional to its square root
   (the energy-norm distance is Hoelder-1/2, not Lipschitz, in the switching times).

Jump bookkeeping and the result (continuum limit, confirmed by the runs at N = 200, 400, 800)
---------------------------------------------------------------------------------------------
A release (contact -> free) is triggered by the arrival of a jump of ``J`` from compression to
tension; the free reflection makes the outgoing characteristic continuous: the release
*annihilates* the arriving jump. A closure (free -> contact) reverses the outgoing
characteristic: it *creates* a jump. On the main backbone of mode k (``t_f = 2kT - 4``) the jump
created at the closure ``c_n`` of period n arrives at the end at ``c_n + 2`` (free phase of
period n + k: reflected) and at ``c_n + 4 = (n + 2k) T`` (release of period n + 2k: annihilated),
so 2k jumps are alive, each for 2k periods. In the free phase of period n the end recedes from
the release ``s_n = c_(n-2k) + 4`` until the reflection ``r_n = c_(n-k) + 2`` and comes back in
the same time, so the closures obey ``c_n = 2 c_(n-k) - c_(n-2k)``, characteristic polynomial
``(lambda^k - 1)^2``: the k-th roots of unity, each a double root (Jordan block).

* k = 1: the only double root, ``lambda = 1``, is the family (phase and period); a period change
  at fixed amplitude is forbidden by the gap (``A = 2 E g0 / (L mu(T))``) and the amplitude is an
  invariant, so switching-time errors cannot accumulate. The thin pulse left by a switching-time
  error is re-emitted with the same width at each micro-impact and transported for ever (no
  decay), but nothing grows. Measured (benchmarks/bench_wfem_stability.py, 8 points, N = 200 and
  400): the L1 orbital distance stays within 2x the initial one for delayed releases and jump
  shifts (also over 1000 periods) and within 3.5x for smooth perturbations (eps = 0.05): the
  mode-1 backbones (g0 > 0 and g0 < 0) are *neutrally stable*: orbitally Lyapunov stable, not
  asymptotically stable, in L1 and in the energy norm (with the square root above).
* k = 2: the double root ``lambda = -1`` is not a symmetry: the two interleaved jump systems
  (even and odd periods) can have slightly different periods, and a perturbation excites that
  Jordan block: alternate periods lengthen and shorten by a number of steps growing linearly in
  time, the jumps drift apart and the L1 orbital distance grows *linearly*, at a rate
  proportional to the perturbation, up to O(0.1-0.8) independently of the perturbation size (then
  it wanders, with recurrences when the relative phase of the two systems comes back; the number
  of jumps stays 4-6: no accumulation of pulses). The time to reach d = 0.1 scales as 1/d0 (not
  log(1/d0)), and the relative distances are identical at N = 100, 200, 400, 800 for the same
  physical perturbation: the mode-2 backbones (g0 < 0, and g0 > 0 as well) are *orbitally
  unstable* (not Lyapunov stable) in L1 and in the energy norm, with algebraic (secular), not
  exponential, growth.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from nsm_continuation.problems.bar.continuum_orbits import (
    Signature,
    continuum_orbit,
    main_signature,
)
from nsm_continuation.problems.bar.wfem_lattice import BarModel, LatticeSolution
from nsm_continuation.problems.bar.wfem_operators import (
    CONTACT,
    FREE,
    floating_bc_contact,
    ring_energy,
    ring_step,
)

NORMS = ("l1", "energy")
KINDS = ("shift", "delay", "smooth", "scale")

GROWTH_CRITERION = (
    "q_k = relative L1 orbital distance d_k, or the relative energy of the difference d_k^2 for "
    "the energy norm (for +-A profiles differing by sign changes only, q_energy = 2 q_L1: both "
    "count displaced jumps linearly), k = 0..P periods; R_k = max_{i<=k} q_i. Reference "
    "q_ref = max(q_0, floor), floor = the grid resolution (two slots of sign mismatch: 2/N in L1, "
    "4/N in energy) and, in energy, also 2 d_L1(0): the jump-equivalent size of the initial "
    "perturbation (a smooth perturbation of L1 size e has energy O(e^2) but displaces the "
    "switching instants by O(e), which costs O(e) energy: the Hoelder-1/2 effect, not growth); "
    "amplification a = R_P / q_ref. 'returns to orbit' if q_k <= 1e-9 over the "
    "last quarter; 'bounded' if a <= 5 over the whole horizon (a resolved perturbation stays "
    "within a few times its size: a finite-horizon test of orbital Lyapunov stability; the "
    "mode-1 runs give a <= 3.5); otherwise growth, fitted on R_k for k = 1..argmax q: "
    "'exponential growth' if log R is better fitted by a line in k (higher R^2) than R itself, "
    "else 'linear growth' (slope per period relative to q_ref and the exponential rate are "
    "reported; 'saturated' if the maximum is reached before 0.9 P). A growth verdict needs a "
    "small q_0: the distance saturates at O(0.1-1), and the growth rate is proportional to q_0 "
    "for linear (secular) growth, which the size scaling of the benchmark checks."
)


# -- floating boundary condition time stepping ------------------------------------------------
@dataclass
class FloatingBCRun:
    """Result of :func:`floating_bc_simulation`.

    ``states[i]`` is the ring state ``w^(n)`` at step ``n = sample_steps[i]`` (before step n);
    ``signs[n]`` the end condition of step n (FREE = -1, CONTACT = +1); ``u_end[n]`` the end
    displacement at the beginning of step n (``u_end[steps]`` at the end); ``J[n]`` the
    characteristic arriving at the end over step n.
    """

    model: BarModel
    sample_steps: np.ndarray
    states: np.ndarray
    signs: np.ndarray
    u_end: np.ndarray
    J: np.ndarray

    @property
    def steps(self) -> int:
        return len(self.signs)

    @property
    def switches(self) -> np.ndarray:
        """Steps ``n > 0`` whose end condition differs from that of step ``n - 1``."""
        return np.nonzero(np.diff(self.signs))[0] + 1

    def pattern(self) -> tuple[tuple[int, int], ...]:
        """The switching pattern as run lengths ``((steps, sign), ...)``."""
        if not len(self.signs):
            return ()
        edges = np.concatenate([[0], self.switches, [len(self.signs)]])
        return tuple((int(b - a), int(self.signs[a])) for a, b in zip(edges[:-1], edges[1:],
                                                                      strict=True))

    def energy(self) -> np.ndarray:
        md = self.model
        return np.array([ring_energy(w, md.dx, md.E) for w in self.states])


def floating_bc_simulation(model: BarModel, w0: np.ndarray, steps: int, *,
                           sample_steps: np.ndarray | list[int] | None = None,
                           u0: float | None = None, closure_tol: float = 1e-9,
                           release_tol: float = 1e-9, left_sign: int = 1,
                           closure: Literal["tolerance", "nearest"] = "tolerance"
                           ) -> FloatingBCRun:
    """Algorithm 2 (floating boundary condition) on the characteristic ring, O(1) per step.

    The specialisation of :func:`problems.bar.wfem_stepping.simulate` to the undamped,
    unforced bar with a fixed wall, on a moving ring origin instead of a rotated array: the
    switching decision is the same function,
    :func:`problems.bar.wfem_operators.floating_bc_contact`, and the end update the same signed
    reflection (B.3)/(B.4). At the beginning of step n, with ``J = w[N-1]`` the characteristic
    arriving at the end (the wall stress of a contact step) and ``g = g0 - u_end`` the gap
    (B.2): the step is CONTACT if the previous step was, or ``g <= closure_tol * dt A / Z``, and
    ``J <= release_tol * A`` (``A = max |w0|``; ``dt A / Z`` is the end displacement over one
    free step, so ``closure_tol = 0.5`` rounds the closure instant to the nearest step instead of
    the first step after the gap closes), FREE otherwise; over a free step ``u_end -= dt J / Z``.
    ``closure="nearest"`` adds the nearest-grid-time closure rule of ``simulate(...,
    switching="grid")`` (with ``closure_tol = release_tol = 0`` the two give the same switching
    sequence and states, tested). ``u_end`` starts at ``u0`` (default: the displacement of the
    state, ``dx/(2E) sum w0``) and is never reset. States are recorded at ``sample_steps``
    (default: 0 and ``steps``).
    """
    N = model.N
    n2 = 2 * N
    w0 = np.asarray(w0, dtype=float)
    if w0.shape != (n2,):
        raise ValueError(f"state must have 2N = {n2} entries")
    if closure not in ("tolerance", "nearest"):
        raise ValueError(f"closure must be 'tolerance' or 'nearest', got {closure!r}")
    nearest = closure == "nearest"
    A = float(np.max(np.abs(w0))) or 1.0
    k_u = model.dt / model.Z
    g_tol = closure_tol * k_u * A
    j_tol = release_tol * A
    g0 = model.g0
    u = model.dx / (2 * model.E) * float(w0.sum()) if u0 is None else float(u0)
    samples = np.array([0, steps] if sample_steps is None else sample_steps, dtype=np.int64)
    if samples.size and (samples.min() < 0 or samples.max() > steps or np.any(np.diff(samples)
                                                                              < 0)):
        raise ValueError("sample_steps must be sorted and within [0, steps]")
    states = np.empty((samples.size, n2))
    buf = w0.tolist()
    off = 0
    signs = [0] * steps
    us = [0.0] * (steps + 1)
    Js = [0.0] * steps
    si = 0
    ns = samples.size
    contact = False
    for n in range(steps):
        while si < ns and samples[si] == n:
            states[si] = np.roll(np.asarray(buf), off)
            si += 1
        j = (N - 1 - off) % n2
        J = buf[j]
        us[n] = u
        Js[n] = J
        g = g0 - u
        contact = floating_bc_contact(contact, g, g + k_u * J, J, nearest, g_tol, j_tol)
        if contact:
            signs[n] = CONTACT
        else:
            signs[n] = FREE
            u -= k_u * J
            buf[j] = -J  # the content of slot N-1 crosses the end with the sign -1
        off += 1
        if left_sign < 0:
            i0 = (-off) % n2
            buf[i0] = -buf[i0]
    us[steps] = u
    while si < ns:
        states[si] = np.roll(np.asarray(buf), off)
        si += 1
    return FloatingBCRun(model, samples, states, np.array(signs, dtype=np.int8), np.array(us),
                         np.array(Js))


# -- the unperturbed orbit and distances --------------------------------------------------------
def orbit_states(sol: LatticeSolution) -> np.ndarray:
    """The M states ``w^(0..M-1)`` of a lattice orbit (rows), O(N M)."""
    N = sol.model.N
    out = np.empty((sol.M, 2 * N))
    w = sol.w0.copy()
    n = 0
    for steps, s in sol.pattern:
        for _ in range(steps):
            out[n] = w
            w = ring_step(w, s, 1, N)
            n += 1
    return out


def _norm(x: np.ndarray, norm: str, axis: int = -1) -> np.ndarray:
    if norm == "l1":
        return np.abs(x).sum(axis=axis)
    if norm in ("energy", "l2"):
        return np.sqrt((x * x).sum(axis=axis))
    raise ValueError(f"unknown norm {norm!r}: use 'l1' or 'energy'")


def orbital_distance(states: np.ndarray, orbit: np.ndarray, norm: str = "l1", *,
                     return_phase: bool = False
                     ) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """``d_i = min_k |states_i - orbit_k| / mean_k |orbit_k|`` (relative distance to the set).

    ``norm``: ``"l1"`` (sum of |w|: the L1 norm of the characteristic profile) or ``"energy"``
    (Euclidean norm of ``w``; the energy is ``dx |w|^2/(4E)``, so ``d^2`` is the energy of the
    difference relative to the orbit's energy). With ``return_phase`` also the index k of the
    nearest orbit state (the phase of the perturbed trajectory on the orbit).

    The Euclidean distances to all M orbit states come from one matrix product; for the L1 norm
    they prune the search exactly (``|x|_1 >= |x|_2^2 / |x|_inf``), so only a few L1 distances
    are evaluated per state.
    """
    states = np.atleast_2d(states)
    orbit = np.atleast_2d(orbit)
    scale = float(np.mean(_norm(orbit, norm)))
    sq = (orbit * orbit).sum(axis=1)
    d2 = np.maximum(sq[None, :] + (states * states).sum(axis=1)[:, None]
                    - 2.0 * states @ orbit.T, 0.0)
    d = np.empty(len(states))
    ph = np.empty(len(states), dtype=np.int64)
    bound = float(np.max(np.abs(orbit))) + np.max(np.abs(states), axis=1)
    for i, s in enumerate(states):
        order = np.argsort(d2[i])
        if norm == "l1":
            best, arg = np.inf, int(order[0])
            for k in order:
                if d2[i, k] / bound[i] > best * (1 + 1e-12):
                    break
                v = float(np.abs(orbit[k] - s).sum())
                if v < best:
                    best, arg = v, int(k)
            d[i], ph[i] = best, arg
        elif norm in ("energy", "l2"):
            k = int(order[0])
            d[i], ph[i] = float(np.sqrt(np.sum((orbit[k] - s) ** 2))), k
        else:
            raise ValueError(f"unknown norm {norm!r}: use 'l1' or 'energy'")
    d /= scale
    return (d, ph) if return_phase else d


# -- the family: continuum members sampled on the grid -----------------------------------------
def _cell_averages(N: int, breaks: np.ndarray, value_at: Any) -> np.ndarray:
    """Cell averages over the 2N ring cells ``[k/N, (k+1)/N)`` of a piecewise-constant function
    of the ring coordinate with breakpoints ``breaks`` (mod 2), evaluated by ``value_at(xi)``."""
    edges = np.arange(2 * N + 1) / N
    pts = np.unique(np.concatenate([edges, np.mod(breaks, 2.0)]))
    mid = 0.5 * (pts[:-1] + pts[1:])
    vals = value_at(mid) * np.diff(pts)
    cell = np.minimum((mid * N).astype(np.int64), 2 * N - 1)
    out = np.zeros(2 * N)
    np.add.at(out, cell, vals)
    return out * N


def continuum_state(model: BarModel, sig: Signature, T: float, t: float,
                    amplitude: float) -> np.ndarray:
    """Cell averages on the ring of the continuum orbit of branch ``sig`` at period ``T``
    (units L/c) and time ``t`` (``t = 0``: start of the free phase), amplitude ``A``.

    The content at ring coordinate ``xi`` at time t started at ``xi0 = xi - t`` with value
    ``A p(xi0)`` and crossed the contact end at ``tau_j = ((1 - xi0) mod 2) + 2j``; each crossing
    in the free phase ``[0, t_f)`` changes its sign (the clamped end keeps it). For integer
    ``T N`` and ``t N`` this is the lattice orbit's state (tested).
    """
    orb = continuum_orbit(sig, T)
    t = float(np.mod(t, T))
    tm = min(t, orb.t_free)

    def value(xi: np.ndarray) -> np.ndarray:
        xi0 = np.mod(xi - t, 2.0)
        r = np.mod(1.0 - xi0, 2.0)
        count = np.where(r < tm, np.floor((tm - r) / 2.0) + 1.0, 0.0)
        return amplitude * orb.profile(xi0) * np.where(count % 2 == 0, 1.0, -1.0)

    breaks = np.concatenate([orb.jumps + t, [1.0 + t - tm, 1.0 + t, 0.0]])
    return _cell_averages(model.N, breaks, value)


def family_member_period(model: BarModel, sig: Signature, energy: float) -> tuple[float, float]:
    """Period T and amplitude A of the member of branch ``sig`` with the given energy.

    ``energy = L A^2 / (2E)`` (S = 1) and ``A = 2 E g0 / (L mu(T))`` with ``mu`` affine in T
    (:mod:`problems.bar.continuum_orbits`); ``mu`` has the sign of ``g0`` on the admissible side.
    """
    A = float(np.sqrt(2 * model.E * energy / model.L))
    mu = 2 * model.E * model.g0 / (model.L * A)
    m0, m1 = float(sig.mu(0.0)), float(sig.mu(1.0))
    return (mu - m0) / (m1 - m0), A


def family_orbit_states(model: BarModel, sig: Signature, energy: float,
                        substeps: int = 2) -> np.ndarray:
    """States of the same-energy member at phases ``t = n dt / substeps`` over one period."""
    T, A = family_member_period(model, sig, energy)
    dt = 1.0 / model.N  # units L/c
    n = int(np.ceil(T / dt * substeps))
    return np.array([continuum_state(model, sig, T, i * dt / substeps, A) for i in range(n)])


def family_distance(states: np.ndarray, model: BarModel, sig: Signature, norm: str = "l1",
                    energy: float | None = None, substeps: int = 2) -> np.ndarray:
    """Orbital distance to the family member with the same energy (module docstring).

    Floor: the member's jumps sit at fractional cell positions, so a lattice profile is at
    relative L1 distance up to about ``(number of jumps) / (4N)`` from it even when on the family.
    """
    e = ring_energy(states[0], model.dx, model.E) if energy is None else energy
    return orbital_distance(states, family_orbit_states(model, sig, e, substeps), norm)


# -- perturbations ---------------------------------------------------------------------------
def profile_jump_slots(w: np.ndarray, rtol: float = 1e-9) -> np.ndarray:
    """Slots k with ``w[k] != w[k-1]`` (around the ring)."""
    scale = float(np.max(np.abs(w))) or 1.0
    return np.nonzero(np.abs(w - np.roll(w, 1)) > rtol * scale)[0]


def _shift_jump(w: np.ndarray, k: int, j: int) -> np.ndarray:
    """Move the jump at slot k (between k-1 and k) by j slots (j > 0: towards larger k)."""
    n = len(w)
    out = w.copy()
    if j > 0:
        out[(k + np.arange(j)) % n] = w[(k - 1) % n]
    elif j < 0:
        out[(k + np.arange(j, 0)) % n] = w[k % n]
    return out


def _jump_shift_options(w: np.ndarray, N: int) -> list[tuple[int, int, int, float]]:
    """Non-trivial jump shifts of an interior jump that stay inside its half of the ring
    (``[0, N)``: the b characteristics, ``[N, 2N)``: the a characteristics; crossing an end would
    move content through a boundary): ``(slot, direction, max_slots, d(sum w)/slot)``."""
    out = []
    for k in profile_jump_slots(w):
        k = int(k)
        if k % N == 0:
            continue
        lo, hi = (0, N) if k < N else (N, 2 * N)
        dv = float(w[(k - 1) % len(w)] - w[k])  # change of sum w per slot moved to the right
        out.append((k, 1, hi - k, dv))
        out.append((k, -1, k - lo, -dv))
    return out


def perturb(model: BarModel, w: np.ndarray, kind: str, eps: float, *, slots: int | None = None,
            seed: int = 0, modes: int = 6) -> tuple[np.ndarray, dict[str, Any]]:
    """The perturbed state and a description, for the kinds ``"shift"``, ``"smooth"`` and
    ``"scale"`` (module docstring; ``"delay"`` needs the orbit: :func:`perturbation_growth`).

    The sign of the perturbation is chosen so that the end displacement ``dx/(2E) sum w`` does
    not increase: applied to a contact state (``u_end = g0``) it opens a gap, never a penetration.
    ``"shift"``: among the jump moves that lower ``sum w`` and stay inside their half ring, the
    one allowing the largest move; ``j = round(eps N)`` slots, clipped to what is feasible (the
    clipped value is reported).
    """
    N = model.N
    A = float(np.max(np.abs(w)))
    info: dict[str, Any] = {"kind": kind}
    if kind == "shift":
        want = slots if slots is not None else max(1, int(round(eps * N)))
        opts = [o for o in _jump_shift_options(w, N) if o[3] < 0 and o[2] >= 1]
        if not opts:
            raise ValueError("no jump shift lowers the end displacement on this state")
        k, direction, room, _ = max(opts, key=lambda o: o[2])
        j = direction * min(want, room)
        out = _shift_jump(w, k, j)
        info.update(slots=j, jump_slot=k, clipped=bool(abs(j) < want))
    elif kind == "smooth":
        rng = np.random.default_rng(seed)
        xi = (np.arange(2 * N) + 0.5) / N
        phi = np.zeros(2 * N)
        for q in range(modes + 1):
            a, b = rng.normal(size=2) / (q + 1)
            phi += a * np.cos(np.pi * q * xi) + b * np.sin(np.pi * q * xi)
        phi /= np.max(np.abs(phi))
        eta = eps * A * phi
        if eta.sum() > 0:
            eta = -eta
        out = w + eta
        info.update(modes=modes, seed=seed)
    elif kind == "scale":
        out = w * (1.0 + eps)
        if out.sum() > w.sum():
            out = w * (1.0 - eps)
        i = int(np.argmax(np.abs(w)))
        info.update(factor=float(out[i] / w[i]))
    else:
        raise ValueError(f"unknown perturbation kind {kind!r}: use one of {KINDS}")
    info["size_l1"] = float(np.abs(out - w).sum() / np.abs(w).sum())
    info["size_energy"] = float(np.linalg.norm(out - w) / np.linalg.norm(w))
    return out, info


# -- growth classification ----------------------------------------------------------------------
def _fit(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """Slope and R^2 of the least-squares line y ~ a + b x."""
    if len(x) < 3 or np.ptp(y) == 0:
        return 0.0, 0.0
    b, a = np.polyfit(x, y, 1)
    ss = float(np.sum((y - y.mean()) ** 2))
    res = float(np.sum((y - (a + b * x)) ** 2))
    return float(b), (1.0 - res / ss) if ss > 0 else 0.0


def classify_growth(q: np.ndarray, floor: float = 0.0, bound_factor: float = 5.0,
                    tiny: float = 1e-9) -> dict[str, Any]:
    """Classify a distance history ``q[k]`` (k = 0: the perturbed state, k = 1..P: after each
    period) by :data:`GROWTH_CRITERION`; ``floor``: the grid resolution of ``q``."""
    q = np.asarray(q, dtype=float)
    P = len(q) - 1
    if P < 1:
        raise ValueError("need at least one period")
    R = np.maximum.accumulate(q)  # running maximum
    ref = max(float(q[0]), floor)
    amp = float(R[P] / ref) if ref > 0 else (np.inf if R[P] > tiny else 1.0)
    k_max = int(np.argmax(q[1:])) + 1
    k = np.arange(1, k_max + 1)
    slope, r2_lin = _fit(k.astype(float), R[k])
    lam, r2_log = _fit(k.astype(float), np.log(R[k])) if R[1] > 0 else (0.0, 0.0)
    if np.max(q[-max(1, P // 4):]) <= tiny:
        label = "returns to orbit"
    elif amp <= bound_factor:
        label = "bounded"
    elif r2_log > r2_lin:
        label = "exponential growth"
    else:
        label = "linear growth"
    return {"label": label, "amplification": amp, "reference": ref, "k_max": k_max,
            "saturated": bool(label.endswith("growth") and k_max < 0.9 * P),
            "slope_rel": float(slope / ref) if ref > 0 else float("inf"), "r2_lin": r2_lin,
            "log_slope": float(lam), "r2_log": r2_log, "max": float(q[1:].max())}


def classify_distances(d: dict[str, np.ndarray], N: int) -> dict[str, dict[str, Any]]:
    """:func:`classify_growth` of the L1 distance (floor 2/N) and of the relative energy of the
    difference ``d_energy^2`` (floor 4/N, and at least ``2 d_L1[0]``), per
    :data:`GROWTH_CRITERION`."""
    out = {}
    if "l1" in d:
        out["l1"] = classify_growth(d["l1"], floor=2.0 / N)
    if "energy" in d:
        floor = max(4.0 / N, 2.0 * float(d["l1"][0])) if "l1" in d else 4.0 / N
        out["energy"] = classify_growth(d["energy"] ** 2, floor=floor)
    return out


@dataclass
class GrowthResult:
    """Distances after each period of a perturbed orbit (:func:`perturbation_growth`)."""

    sol: LatticeSolution
    kind: str
    eps: float
    info: dict[str, Any]
    start_step: int
    periods: np.ndarray
    distance: dict[str, np.ndarray]
    family: dict[str, np.ndarray]
    phase: np.ndarray
    energy_drift: float
    switches_per_period: float
    classification: dict[str, dict[str, Any]] = field(default_factory=dict)
    run: FloatingBCRun | None = None


def perturbation_step(sol: LatticeSolution, at: str = "contact",
                      orbit: np.ndarray | None = None) -> int:
    """Step of the orbit where a perturbation is applied.

    ``"contact"``: the middle of the (first) contact phase. On the mode-1 backbone only the
    contact-phase states have two interior profile jumps (free-phase states are uniform plus one
    jump, so shifting it is a mere phase shift and stays on the orbit); there ``u_end = g0`` and
    the perturbation is applied with the sign that opens the gap. ``"free"``: the widest gap.
    """
    if at == "contact":
        m, p = sol.counts[0], sol.counts[1]
        return int(m + p // 2)
    if at == "free":
        md = sol.model
        orbit = orbit_states(sol) if orbit is None else orbit
        return int(np.argmax(md.g0 - md.dx / (2 * md.E) * orbit.sum(axis=1)))
    raise ValueError("at must be 'contact' or 'free'")


def perturbation_growth(sol: LatticeSolution, eps: float, periods: int, kind: str = "shift", *,
                        at: str = "contact", norms: tuple[str, ...] = NORMS, family: bool = True,
                        signature: Signature | None = None, closure_tol: float = 1e-9,
                        keep_run: bool = False, **perturb_kw: Any) -> GrowthResult:
    """Perturb the orbit ``sol``, step ``periods`` periods with the floating boundary condition
    and measure the orbital distance after each period.

    ``kind``: ``"shift"``, ``"smooth"``, ``"scale"`` (:func:`perturb`, applied at
    :func:`perturbation_step` ``at``) or ``"delay"``: the release (contact -> free switch at
    step 0 of the orbit) is delayed by ``j = round(eps N)`` steps, i.e. the end is held on the
    obstacle (an adhesive, energy-free constraint force) for j steps while the arriving wave is
    tensile: a switching-time perturbation resolved by the grid, which leaves a thin pulse of
    width j and height 2A in the outgoing wave (u_end stays g0: an admissible, consistent
    state).
    ``family``: also the distance to the same-energy member of the branch ``signature``
    (default: the main backbone with the profile's jump count, ``main_signature(jumps/2)``).
    Returns ``d[k]``, k = 0..periods (k = 0: the perturbed state), and their classification.
    """
    md = sol.model
    orbit = orbit_states(sol)
    M = sol.M
    if kind == "delay":
        j = perturb_kw.pop("slots", None) or max(1, int(round(eps * md.N)))
        if perturb_kw:
            raise TypeError(f"unexpected arguments for 'delay': {sorted(perturb_kw)}")
        n0 = 0
        w_start = orbit[0].copy()
        for _ in range(j):
            w_start = ring_step(w_start, CONTACT, 1, md.N)
        info = {"kind": "delay", "slots": j,
                "size_l1": float(np.abs(w_start - orbit[j % M]).sum() / np.abs(orbit[0]).sum()),
                "size_energy": float(np.linalg.norm(w_start - orbit[j % M])
                                     / np.linalg.norm(orbit[0]))}
    else:
        n0 = perturbation_step(sol, at, orbit)
        w_start, info = perturb(md, orbit[n0], kind, eps, **perturb_kw)
    steps = periods * M
    run = floating_bc_simulation(md, w_start, steps, sample_steps=np.arange(periods + 1) * M,
                                 closure_tol=closure_tol)
    dist: dict[str, np.ndarray] = {}
    phase = np.zeros(periods + 1, dtype=np.int64)
    for nm in norms:
        dist[nm], phase = orbital_distance(run.states, orbit, nm, return_phase=True)
    fam: dict[str, np.ndarray] = {}
    if family:
        if signature is None:
            signature = main_signature(max(1, len(profile_jump_slots(sol.w0)) // 2))
        fam_orbit = family_orbit_states(md, signature, ring_energy(w_start, md.dx, md.E))
        for nm in norms:
            fam[nm] = orbital_distance(run.states, fam_orbit, nm)
    en = run.energy()
    drift = float(np.max(np.abs(en / en[0] - 1.0)))
    return GrowthResult(sol, kind, eps, info, n0, np.arange(periods + 1), dist, fam, phase, drift,
                        len(run.switches) / max(periods, 1),
                        classify_distances(dist, md.N),
                        run if keep_run else None)


# -- backbone points ----------------------------------------------------------------------------
def main_backbone_counts(N: int, M: int, mode: int = 1) -> tuple[int, int]:
    """Lattice node of the main backbone of mode k at period M: ``m = 2k M - 4N``."""
    m = 2 * mode * M - 4 * N
    return m, M - m
