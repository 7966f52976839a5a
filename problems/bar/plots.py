"""Figures of the WFEM bar orbits (Yoong, Thorin, Legrand 2017, section 6).

Reconstructions from a :class:`~problems.bar.wfem_lattice.LatticeSolution` (ring layout of
:mod:`problems.bar.wfem_operators`: slots ``0..N-1`` hold ``b_i = sigma_i - Z v_i``, slots
``N..2N-1`` hold ``a_N..a_1`` with ``a_i = sigma_i + Z v_i``):

* the displacement at the cell interfaces ``x_(i+1/2) = i dx`` (the bar is clamped at x = 0)::

      u(x_(i+1/2), t_n) = (dx / E) sum_(j <= i) sigma_j^(n),   u_(1/2) = 0,

  so ``u_(N+1/2)`` is the contact-end displacement and ``u_(3/2) = dx sigma_1 / E``;
* the contact-end velocity over step n, ``-J[n] / Z`` in free steps and 0 in contact steps, and
  the contact force ``lambda = -sigma(L) = -J[n] >= 0`` in contact steps (COND2), 0 when free.

The two reconstructions of ``u_(N+1/2)`` (stress sum, time integral of the end velocity from
``u_(N+1/2)(0) = g0``) agree to round-off (``tests/bar/test_wfem_plots.py``).

Figures:

* :func:`space_time`: the field ``u(x, t)`` (Figs. 8a, 10a, 13, 17), with the characteristic
  lines ``t = +-x/c`` through the origin (reflected at both ends), contact closures and grazing
  instants;
* :func:`end_time_series`: ``u(L, t)`` with the gap, the contact phases and the contact force
  (Figs. 8c-e, 13, 15);
* :func:`manifold_section`: the orbits of a branch in the cross-section
  ``(u_(N+1/2), v_(N+1/2), u_(3/2))`` of the state space (Figs. 9, 11, 14), with the plane
  ``u_(N+1/2) = g0`` and, for ``g0 > 0``, the linear portion (elliptical disk of the first
  fixed-free mode with amplitude ``A <= g0``, Fig. 9);
* :func:`extra_plots`: the three figures for the branches of a continuation run.

Units: t in ``L / c``, x in L, displacements in ``|g0|``, velocities in ``c |g0| / L`` and the
contact force in ``E S |g0| / L`` (S = 1); absolute values when ``g0 = 0``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from nsm_continuation.problems.bar.wfem_lattice import (
    BarModel,
    LatticeSolution,
    grazing_representative,
)
from nsm_continuation.problems.bar.wfem_operators import CONTACT, ring_step

# -- reconstructions ------------------------------------------------------------------------------


@dataclass(frozen=True)
class Field:
    """Displacement field at the cell interfaces over ``periods`` periods.

    ``steps[r]`` is the time step of row r (``t = steps * dt``); ``u[r, i]`` the displacement at
    ``x_(i+1/2) = i dx`` (``i = 0..N``; column 0 is the clamped end, column N the contact end).
    """

    steps: np.ndarray
    x: np.ndarray
    u: np.ndarray


def step_signs(sol: LatticeSolution) -> np.ndarray:
    """End sign of every step of one period: FREE (-1) or CONTACT (+1), pattern order (11)/(18)."""
    return np.concatenate([np.full(n, s, dtype=np.int64) for n, s in sol.pattern])


def contact_mask(sol: LatticeSolution) -> np.ndarray:
    """True on the contact steps of one period."""
    return step_signs(sol) == CONTACT


def end_velocity(sol: LatticeSolution) -> np.ndarray:
    """``v_(N+1/2)`` over each step of one period: ``-J[n] / Z`` free, 0 in contact (B.3-B.4)."""
    return np.where(contact_mask(sol), 0.0, -sol.J / sol.model.Z)


def contact_force(sol: LatticeSolution) -> np.ndarray:
    """Compressive contact force ``lambda = -S sigma(L) = -J[n]`` over each step (0 when free)."""
    return np.where(contact_mask(sol), -sol.J, 0.0)


def displacement_field(sol: LatticeSolution, periods: float = 1.0, max_rows: int | None = None
                       ) -> Field:
    """``u(x_(i+1/2), t_n)`` from the stresses, for ``n = 0..round(periods M)``.

    The ring is advanced step by step (:func:`~problems.bar.wfem_operators.ring_step`) and only
    every ``stride``-th state is kept, ``stride`` chosen so that at most ``max_rows`` rows are
    stored (all steps when None): O(N) memory per kept row.
    """
    md = sol.model
    N, M = md.N, sol.M
    n_steps = max(1, int(round(periods * M)))
    stride = 1 if max_rows is None else max(1, int(np.ceil((n_steps + 1) / max_rows)))
    signs = step_signs(sol)
    keep = np.arange(0, n_steps + 1, stride)
    rows = np.empty((len(keep), N + 1))
    w = np.array(sol.w0, dtype=float)
    rows[:, 0] = 0.0
    r = 0
    for n in range(n_steps + 1):
        if r < len(keep) and n == keep[r]:
            sigma = 0.5 * (w[:N] + w[N:][::-1])  # (a_i + b_i) / 2, i = 1..N
            rows[r, 1:] = np.cumsum(sigma) * md.dx / md.E
            r += 1
        if n < n_steps:
            w = ring_step(w, int(signs[n % M]), 1, N)
    return Field(keep, np.arange(N + 1) * md.dx, rows)


def orbit_section(sol: LatticeSolution) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The orbit in the cross-section ``(u_(N+1/2), v_(N+1/2), u_(3/2))`` (Fig. 9), closed.

    Over step n the end velocity is constant and both displacements are affine in t, so the
    trajectory is the polyline ``(u_n, v_n, u3_n) -> (u_(n+1), v_n, u3_(n+1))``; the velocity
    jumps between steps (the discontinuity along the velocity direction of section 6.1). Returns
    arrays of 2M points.
    """
    f = displacement_field(sol, 1.0)
    u_end, u3 = f.u[:, -1], f.u[:, 1]
    v = end_velocity(sol)
    U = np.empty(2 * sol.M)
    V = np.empty(2 * sol.M)
    U3 = np.empty(2 * sol.M)
    U[0::2], U[1::2] = u_end[:-1], u_end[1:]
    U3[0::2], U3[1::2] = u3[:-1], u3[1:]
    V[0::2] = V[1::2] = v
    return U, V, U3


def event_steps(sol: LatticeSolution) -> tuple[list[int], list[int]]:
    """(contact closures, contact openings) as steps of one period (pattern starts free)."""
    closures, openings = [], []
    t = 0
    for j, c in enumerate(sol.counts):
        (openings if j % 2 == 0 else closures).append(t)
        t += c
    return closures, openings


def scales(model: BarModel) -> tuple[float, float, float, str]:
    """(displacement, velocity, force) units and the displacement label suffix."""
    g = abs(model.g0)
    if g == 0:
        return 1.0, 1.0, 1.0, ""
    return g, model.c * g / model.L, model.E * g / model.L, r" / |g_0|"


# -- figures --------------------------------------------------------------------------------------


def _times_in(steps: list[int], M: int, n_max: int) -> np.ndarray:
    """All ``s + j M`` in ``[0, n_max]`` for s in steps."""
    out = [s + j * M for s in steps for j in range(int(n_max // M) + 2) if 0 <= s + j * M <= n_max]
    return np.unique(np.array(out, dtype=float))


def space_time(ax: Any, sol: LatticeSolution, periods: float = 2, *, colorbar: bool = True,
               max_rows: int = 1200) -> Any:
    """Space-time plot of ``u(x, t)`` over ``periods`` periods (Figs. 8a, 10a, 13, 17).

    x horizontal in [0, L], t vertical in units of L/c; colormap 'Greens' from the smallest
    displacement (white) to the largest (dark green), zero included in the range: positive
    displacement dark green, negative white (captions of Figs. 8, 10, 13, 17; for ``g0 < 0`` zero
    is dark green, Fig. 15). Black dashed: the characteristic lines ``t = +-x/c`` through the
    origin, reflected at both ends; white dashed: contact closures; black dotted: grazing
    instants (Fig. 13). Returns the image.
    """
    import matplotlib.patheffects as pe

    md = sol.model
    us, _, _, suffix = scales(md)
    f = displacement_field(sol, periods, max_rows=max_rows)
    U = f.u / us
    t_unit = md.L / md.c
    t = f.steps * md.dt / t_unit
    t_end = float(t[-1])
    dt_row = (t[1] - t[0]) if len(t) > 1 else md.dt / t_unit
    lo, hi = min(float(U.min()), 0.0), max(float(U.max()), 0.0)
    if hi == lo:
        hi = lo + 1.0
    xe = md.dx / md.L / 2
    im = ax.imshow(U, origin="lower", aspect="auto", cmap="Greens", vmin=lo, vmax=hi,
                   interpolation="nearest",
                   extent=(-xe, 1 + xe, -dt_row / 2, t_end + dt_row / 2))
    # characteristics through the origin and their reflections: t = +-x/c + 2k L/c
    xi = np.array([0.0, 1.0])
    for k in range(int(np.ceil(t_end / 2)) + 1):
        for tt in (2 * k + xi, 2 * k - xi):
            ax.plot(xi, tt, color="k", ls="--", lw=0.7)
    n_max = int(f.steps[-1])
    closures, _ = event_steps(sol)
    halo = [pe.withStroke(linewidth=2.2, foreground="0.35")]
    for tc in _times_in(closures, sol.M, n_max) * md.dt / t_unit:
        ax.axhline(tc, color="w", ls="--", lw=1.1, path_effects=halo)
    for tg in _times_in(list(sol.grazing_steps), sol.M, n_max) * md.dt / t_unit:
        ax.axhline(tg, color="k", ls=":", lw=1.2)
    ax.set_xlim(0, 1)
    ax.set_ylim(0, t_end)
    ax.set_xlabel(r"$x / L$")
    ax.set_ylabel(r"$t\,c / L$")
    if colorbar:
        cb = ax.figure.colorbar(im, ax=ax, pad=0.02)
        cb.set_label(r"$u(x,t)" + suffix + "$")
    return im


def end_time_series(ax: Any, sol: LatticeSolution, periods: float = 2, *,
                    force: bool = True) -> Any:
    """Contact-end displacement ``u(L, t)`` and contact force vs ``t c / L`` (Figs. 8c-e, 13, 15).

    Black: ``u_(N+1/2)`` (from the stresses; affine over each step); dashed: the gap
    ``u = g0``; shaded: contact phases; dotted verticals: grazing instants. With ``force``, a twin
    axis carries the compressive contact force ``lambda = -sigma(L) >= 0`` (red steps; piecewise
    constant on the main backbones, section 6.1). Returns the twin axis (or None).
    """
    md = sol.model
    us, _, fs, suffix = scales(md)
    f = displacement_field(sol, periods)
    t_unit = md.L / md.c
    t = f.steps * md.dt / t_unit
    n_max = int(f.steps[-1])
    ax.plot(t, f.u[:, -1] / us, color="k", lw=1.2, label=r"$u(L,t)$")
    ax.axhline(md.g0 / us, color="0.4", ls="--", lw=0.9, label=r"gap $g_0$")
    mask = contact_mask(sol)
    n = np.arange(n_max)
    contact = mask[n % sol.M]
    # shade the contact runs
    edges = np.flatnonzero(np.diff(np.concatenate([[0], contact.astype(int), [0]])))
    for a, b in zip(edges[0::2], edges[1::2], strict=True):
        ax.axvspan(a * md.dt / t_unit, b * md.dt / t_unit, color="tab:orange", alpha=0.18, lw=0)
    for tg in _times_in(list(sol.grazing_steps), sol.M, n_max) * md.dt / t_unit:
        ax.axvline(tg, color="k", ls=":", lw=1.0)
    ax.set_xlim(0, t[-1])
    ax.set_xlabel(r"$t\,c / L$")
    ax.set_ylabel(r"$u(L,t)" + suffix + "$")
    if not force:
        return None
    lam = contact_force(sol)[n % sol.M] / fs
    ax2 = ax.twinx()
    ax2.stairs(lam, np.arange(n_max + 1) * md.dt / t_unit, color="tab:red", lw=1.0,
               baseline=None)
    ax2.set_ylabel(r"$\lambda = -\sigma(L)$" + ("" if md.g0 == 0 else r" $/\,(E|g_0|/L)$"),
                   color="tab:red")
    ax2.tick_params(axis="y", colors="tab:red")
    top = float(lam.max()) if lam.size else 0.0
    ax2.set_ylim(-0.05 * (top or 1.0), 1.6 * (top or 1.0))
    return ax2


def manifold_section(ax3d: Any, solutions: list[LatticeSolution], g0: float | None = None, *,
                     cmap: str = "viridis", colorbar: bool = True) -> None:
    """Invariant-manifold cross-section ``(u_(N+1/2), v_(N+1/2), u_(3/2))`` (Figs. 9, 11, 14).

    Each orbit of the branch is drawn as a closed curve coloured by its energy ratio ``E/E_ref``
    (log scale); their union sweeps the manifold (flat pieces, discontinuous along the velocity
    direction). Gray translucent surface: the Poincare section ``u_(N+1/2) = g0``. For
    ``g0 > 0`` the linear portion: the elliptical disk traced by the first fixed-free mode
    ``u = A sin(pi x / 2L) cos(omega_1 t)``, ``A <= g0``, with ``u_(3/2) = A sin(pi dx / 2L)
    cos(omega_1 t)`` at the interface ``x_(3/2) = dx`` (Fig. 9: not connected to the nonlinear
    portion, internal resonance).
    """
    import matplotlib as mpl
    from matplotlib import cm, colors
    from mpl_toolkits.mplot3d.art3d import Line3DCollection

    if not solutions:
        return
    md = solutions[0].model
    g0 = md.g0 if g0 is None else g0
    us, vs, _, suffix = scales(md)
    energies = np.array([s.energy / md.energy_ref for s in solutions])
    lo, hi = float(energies.min()), float(energies.max())
    norm = colors.LogNorm(lo, hi) if 0 < lo < hi else colors.Normalize(lo, hi if hi > lo
                                                                         else lo + 1)
    cmap_obj = mpl.colormaps[cmap]
    segs, cols = [], []
    ranges = np.array([[np.inf, -np.inf]] * 3)
    for s, e in zip(solutions, energies, strict=True):
        U, V, U3 = orbit_section(s)
        P = np.column_stack([U / us, V / vs, U3 / us])
        P = np.vstack([P, P[:1]])
        segs.append(P)
        cols.append(cmap_obj(norm(e)))
        ranges[:, 0] = np.minimum(ranges[:, 0], P.min(axis=0))
        ranges[:, 1] = np.maximum(ranges[:, 1], P.max(axis=0))
    ax3d.add_collection3d(Line3DCollection(segs, colors=cols, linewidths=0.8))
    if g0 > 0:
        th = np.linspace(0, 2 * np.pi, 121)
        A = np.linspace(0, g0, 6)
        s3 = np.sin(np.pi * md.dx / (2 * md.L))
        AA, TT = np.meshgrid(A, th)
        X, Y, Z = (AA * np.cos(TT) / us, -AA * md.omega1 * np.sin(TT) / vs,
                   AA * s3 * np.cos(TT) / us)
        ax3d.plot_surface(X, Y, Z, color="tab:blue", alpha=0.25, lw=0, shade=False)
        ax3d.plot(X[:, -1], Y[:, -1], Z[:, -1], color="tab:blue", lw=1.2,
                  label=r"linear mode 1, $A \leq g_0$")
        for k, arr in enumerate((X, Y, Z)):
            ranges[k, 0] = min(ranges[k, 0], float(arr.min()))
            ranges[k, 1] = max(ranges[k, 1], float(arr.max()))
    pad = 0.05 * (ranges[:, 1] - ranges[:, 0] + 1e-30)
    lims = np.column_stack([ranges[:, 0] - pad, ranges[:, 1] + pad])
    vv, ww = np.meshgrid(lims[1], lims[2])
    ax3d.plot_surface(np.full_like(vv, g0 / us), vv, ww, color="0.5", alpha=0.2, lw=0,
                      shade=False)
    ax3d.set_xlim(*lims[0])
    ax3d.set_ylim(*lims[1])
    ax3d.set_zlim(*lims[2])
    ax3d.set_xlabel(r"$u_{N+1/2}" + suffix + "$")
    ax3d.set_ylabel(r"$v_{N+1/2}$" + ("" if md.g0 == 0 else r" $/\,(c|g_0|/L)$"))
    ax3d.set_zlabel(r"$u_{3/2}" + suffix + "$")
    if colorbar:
        sm = cm.ScalarMappable(norm=norm, cmap=cmap_obj)
        cb = ax3d.figure.colorbar(sm, ax=ax3d, shrink=0.6, pad=0.1)
        cb.set_label(r"$E / E_{ref}$ (eq. 14)")


# -- run output -----------------------------------------------------------------------------------


def _counts_of(derived: dict[str, Any]) -> tuple[int, ...] | None:
    """Lattice node of a branch point: (m, p), or (m, p, k, p) for two contact phases (18)."""
    try:
        m, p = int(derived["m"]), int(derived["p"])
    except (KeyError, TypeError, ValueError):
        return None
    phases = int(derived.get("contact_phases", 1))
    if phases == 1:
        return (m, p)
    if phases == 2 and "M" in derived:  # the continuation keeps p = l (wfem_bar.lattice_next)
        k = int(derived["M"]) - m - 2 * p
        return (m, p, k, p) if k >= 1 else None
    return None


def resolve_point(problem: Any, derived: dict[str, Any]) -> LatticeSolution | None:
    """The orbit of a branch point, re-solved at its node (energy closest to the stored one).

    For ``g0 = 0`` (amplitude free) the node may have no unique candidate: the representative of
    :func:`~problems.bar.wfem_lattice.grazing_representative` is used, scaled to the stored energy.
    """
    counts = _counts_of(derived)
    if counts is None:
        return None
    try:
        sols = list(problem.physical(counts))
    except ValueError:
        sols = []
    md: BarModel = problem.model
    if not sols and md.g0 == 0 and len(counts) == 2:
        rep = grazing_representative(md, counts)
        sols = [rep] if rep is not None else []
    if not sols:
        return None
    target = derived.get("energy")
    if target is None or not np.isfinite(target) or target <= 0:
        return sols[0]
    sol = min(sols, key=lambda s: abs(np.log(s.energy / target)))
    if sol.amplitude_free and sol.energy > 0:
        k = float(np.sqrt(target / sol.energy))
        sol = dataclasses.replace(sol, w0=sol.w0 * k, J=sol.J * k, energy=sol.energy * k * k)
    return sol


def _chosen_points(points: list[Any], k: int = 3) -> list[Any]:
    """Up to k points of a branch: lowest, middle and highest energy ratio."""
    pts = [p for p in points if "energy_ratio" in p.derived and _counts_of(p.derived)]
    if not pts:
        return []
    pts.sort(key=lambda p: p.derived["energy_ratio"])
    idx = sorted({0, len(pts) // 2, len(pts) - 1})[:k]
    return [pts[i] for i in idx]


def _manifold_points(points: list[Any], k: int, factor: float) -> list[Any]:
    """Up to k points of a branch for the manifold section, evenly spaced in amplitude.

    Points with ``E/E_ref`` above ``factor`` times the lowest one are dropped (when at least three
    remain): the energy grows without bound towards the asymptote and the largest orbits would
    hide the others (and the linear disk of Fig. 9).
    """
    pts = sorted((p for p in points if "energy_ratio" in p.derived and _counts_of(p.derived)),
                 key=lambda p: p.derived["energy_ratio"])
    if not pts:
        return []
    e0 = pts[0].derived["energy_ratio"]
    low = [p for p in pts if p.derived["energy_ratio"] <= factor * e0]
    if len(low) >= 3:
        pts = low
    if len(pts) > k:
        amp = np.sqrt(np.maximum([p.derived["energy_ratio"] for p in pts], 0.0))
        targets = np.linspace(amp[0], amp[-1], k)
        idx = np.unique(np.searchsorted(amp, targets).clip(0, len(pts) - 1))
        pts = [pts[i] for i in idx]
    return pts


def _title(sol: LatticeSolution, d: dict[str, Any]) -> str:
    tag = ", ".join(str(c) for c in sol.counts)
    return (rf"$\omega/\omega_1$ = {d['omega_ratio']:.4f}, $E/E_{{ref}}$ = "
            f"{d['energy_ratio']:.3g}\n(m, p) = ({tag})")


def extra_plots(out_dir: Path, branches: list[Any], problem: Any, *, max_branches: int = 4,
                max_orbits: int = 24, manifold_energy_factor: float = 25.0) -> list[str]:
    """``space_time.png``, ``end_displacement.png``, ``manifold_section.png`` for a run.

    Up to three points per branch (lowest, middle, highest energy; the first ``max_branches``
    branches) are re-solved at their lattice node (``problem.physical``) and drawn as in Figs. 8
    and 13; the manifold section (Fig. 9) uses up to ``max_orbits`` points of the first branch
    with points, with ``E/E_ref`` up to ``manifold_energy_factor`` times its lowest value
    (:func:`_manifold_points`). Returns the names of the files written ([] when there is nothing
    to draw).
    """
    from matplotlib.figure import Figure

    out_dir = Path(out_dir)
    rows: list[list[tuple[LatticeSolution, dict[str, Any]]]] = []
    first_branch = None
    for br in branches or []:
        pts = list(getattr(br, "points", []) or [])
        if not pts:
            continue
        if first_branch is None:
            first_branch = pts
        if len(rows) >= max_branches:
            continue
        row = []
        for p in _chosen_points(pts):
            sol = resolve_point(problem, p.derived)
            if sol is not None:
                row.append((sol, p.derived))
        if row:
            rows.append(row)
    files: list[str] = []
    if rows:
        ncol = max(len(r) for r in rows)
        for name, draw, size in (("space_time.png", space_time, (4.4, 3.8)),
                                 ("end_displacement.png", end_time_series, (4.6, 3.0))):
            fig = Figure(figsize=(size[0] * ncol, size[1] * len(rows)))
            axes = fig.subplots(len(rows), ncol, squeeze=False)
            for i, row in enumerate(rows):
                for j in range(ncol):
                    ax = axes[i, j]
                    if j >= len(row):
                        ax.set_axis_off()
                        continue
                    sol, d = row[j]
                    draw(ax, sol, 2)
                    ax.set_title(_title(sol, d), fontsize=8)
            fig.suptitle("WFEM bar: " + ("displacement field u(x, t), Figs. 8a, 10a, 13"
                                         if name == "space_time.png" else
                                         "contact-end displacement and contact force, "
                                         "Figs. 8c-e, 13, 15"), fontsize=10)
            fig.tight_layout()
            fig.savefig(out_dir / name, dpi=110)
            files.append(name)
    if first_branch:
        pts = _manifold_points(first_branch, max_orbits, manifold_energy_factor)
        sols = [s for s in (resolve_point(problem, p.derived) for p in pts) if s is not None]
        if sols:
            fig = Figure(figsize=(7.5, 6.0))
            ax = fig.add_subplot(projection="3d")
            manifold_section(ax, sols, problem.model.g0)
            ax.set_title(r"Invariant manifold section $(u_{N+1/2}, v_{N+1/2}, u_{3/2})$, "
                         f"first branch, {len(sols)} orbits (Figs. 9, 11, 14)", fontsize=9)
            if problem.model.g0 > 0:
                ax.legend(fontsize=8, loc="upper left")
            fig.savefig(out_dir / "manifold_section.png", dpi=110)
            files.append("manifold_section.png")
    return files
