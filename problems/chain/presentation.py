"""Presentation of the chain's results: the frequency-energy plot of Fig. 3.2 with its
references, the ``w_N`` figure (Fig. 3.1), the orbits (Figs. 5.2-5.10, 7.2, 7.4), the CSV
columns, the report's facts, warnings and extras (Legrand, Junca, Heng 2017).

:class:`ChainPresentation` is the chain's
:class:`~nsm_continuation.core.presentation.Presentation`: pure functions of the results and of
what the problem was built from, reading the problem through ``self.problem``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from nsm_continuation.core.presentation import Presentation
from nsm_continuation.core.records import OrbitTrace

#: the model a run of ``ndof_impact`` uses, for the report (``problem_summary.model``)
MODEL = ("closed form (Legrand, Junca, Heng 2017, eqs. 4.1-4.2, multipliers from A.8): the "
         "default model of the one-impact orbits, exact where their assumptions hold (one "
         "impact per period); problem ndof_impact_hybrid simulates the same chain")


class ChainPresentation(Presentation):
    """Presentation members of
    :class:`~nsm_continuation.problems.chain.ndof_impact.NDofImpactProblem`. They read from the
    problem its sizes and modal data (``N``, ``c``, ``g``, ``formulation``, ``omega``, ``P``,
    ``Pinv``, ``M``, ``T_lin``, ``a``) and the methods ``state``, ``w_N``, ``poles``,
    ``zeros_of_w_N``, ``grazing_energy``, ``internal_resonances`` and
    ``static_grazing_spectrum``."""

    #: the diagram: the frequency-energy plot of Fig. 3.2
    fep_axes = ("omega", "energy")
    fep_labels = (r"frequency $\omega = 2\pi/T$ [rad/s]",
                  r"energy $E = \frac{1}{2}(\dot u^T M \dot u + u^T K u)$")
    diagram_title: ClassVar[str] = "Frequency-energy plot"
    #: labels of the chain's quantities and parameters in every figure
    LABELS: ClassVar[dict[str, str]] = {
        "omega": r"frequency $\omega = 2\pi/T$ [rad/s]", "T": "period $T$ [s]",
        "energy": r"energy $E = \frac{1}{2}(\dot u^T M \dot u + u^T K u)$",
        "stiffness": "stiffness $k$", "mass": "mass $m$", "gap": "gap $g$"}
    diagram_yscale: ClassVar[str] = "log"
    csv_head = ["T", "omega", "energy"]
    event_columns = ["omega", "T", "energy"]
    #: largest subharmonic order k of the references omega_j / k (Fig. 3.2) and of the poles
    #: k T_j drawn in Fig. 3.1
    SUBHARMONIC_KMAX: ClassVar[int] = 10

    #: samples per period of :meth:`orbit`: at least this many, and at least
    #: ``ORBIT_SAMPLES_PER_OSCILLATION`` per period of the fastest mode
    ORBIT_SAMPLES: ClassVar[int] = 600
    ORBIT_SAMPLES_PER_OSCILLATION: ClassVar[int] = 40

    @property
    def quantity_labels(self) -> dict[str, str]:
        return dict(self.LABELS)

    def orbit(self, y: np.ndarray, periods: int = 1) -> OrbitTrace:
        """The orbit at ``y`` in closed form: from the post-impact state ``(u(0), u'(0+))``
        the free flight of the linear chain (eqs. 2.9-2.10, (5.4) for ``u_c``),
        ``u(t) = P (cos(Omega t) q + Omega^-1 sin(Omega t) p)`` with ``q = P^-1 u(0)``,
        ``p = P^-1 u'(0+)``, on ``[0, T]`` (the last sample is the state ``u'(T-)`` before
        the impact), repeated ``periods`` times (the impact law ``u_c'+ = -u_c'-`` maps the
        state at ``T-`` to the one at ``0``: a fixed point of the return map). Signals
        ``u1..uN``, ``du1..duN``; views: ``u_c`` against ``t / T`` (Figs. 5.2, 5.7), the phase
        portrait ``(u_c, u_c')`` (Fig. 5.10) and the manifold ``(u_{c-1}, u_c, u_c')``
        (Figs. 5.4-5.9, 7.2, 7.4); an impact mark at every ``t = k T``."""
        u0, du0, T = self.problem.state(y)
        w = self.problem.omega
        q, p = self.problem.Pinv @ u0, self.problem.Pinv @ du0
        n = max(self.ORBIT_SAMPLES,
                int(np.ceil(self.ORBIT_SAMPLES_PER_OSCILLATION * w.max() * T / (2 * np.pi))))
        s = np.linspace(0.0, T, n)
        wt = np.multiply.outer(s, w)
        cw, sw = np.cos(wt), np.sin(wt)
        U = (cw * q + sw * (p / w)) @ self.problem.P.T
        dU = (-sw * (w * q) + cw * p) @ self.problem.P.T
        k = int(periods)
        t = np.concatenate([s + j * T for j in range(k)])
        signals: dict[str, np.ndarray] = {}
        labels: dict[str, str] = {}
        for i in range(self.problem.N):
            signals[f"u{i + 1}"] = np.tile(U[:, i], k)
            signals[f"du{i + 1}"] = np.tile(dU[:, i], k)
            labels[f"u{i + 1}"] = rf"displacement $u_{{{i + 1}}}$"
            labels[f"du{i + 1}"] = rf"velocity $\dot u_{{{i + 1}}}$"
        return OrbitTrace(t=t, period=T, signals=signals, labels=labels,
                          marks=[(j * T, "impact") for j in range(k + 1)],
                          views=self.orbit_signal_views())

    def orbit_signal_views(self) -> dict[str, tuple[str, ...]]:
        """The views of :meth:`orbit` with their signals: ``u_c`` against ``t / T``, the phase
        portrait ``(u_c, u_c')`` and, for ``N > 1``, the manifold ``(u_{c-1}, u_c, u_c')``
        (the neighbour ``u_2`` for ``c = 1``)."""
        c = f"{self.problem.c + 1}"
        views: dict[str, tuple[str, ...]] = {"time": (f"u{c}",), "phase": (f"u{c}", f"du{c}")}
        if self.problem.N > 1:
            # the neighbour of the impacting dof (1-based)
            other = self.problem.c if self.problem.c > 0 else 2
            views["manifold"] = (f"u{other}", f"u{c}", f"du{c}")
        return views

    def orbit_view_names(self) -> tuple[str, ...]:
        """The views of :meth:`orbit_signal_views` (no manifold for one degree of freedom)."""
        return tuple(self.orbit_signal_views())

    # ------------------------------------------------------------------ hooks
    def warnings(self) -> list[str]:
        w = self.problem.internal_resonances()
        off = np.delete(self.problem.M[self.problem.c, :], self.problem.c)
        if np.any(off != 0.0):
            w.append("M couples the impacting dof to the others (M_ck != 0): the impact law "
                     "u_c'+ = -u_c'- does not conserve energy (Prop. 6.1)")
        if np.any(np.abs(self.problem.a) < 1e-12):
            w.append("an interaction coefficient a_j vanishes (Assumption 2.1 violated)")
        return w

    def summary(self) -> dict[str, Any]:
        pr = self.problem
        return {"model": MODEL, "N": pr.N, "impacting_dof": pr.c + 1, "gap": pr.g,
                "omega_linear": pr.omega.tolist(), "T_linear": pr.T_lin.tolist(),
                "interaction_coefficients": self.problem.a.tolist(),
                "alpha": float(np.sum(self.problem.a / self.problem.omega**2)),
                "formulation": self.problem.formulation}

    # ------------------------------------------------------------------ report and figure hooks
    def plot_decorations(self, ax: Any, x_range: tuple[float, float],
                         branches: list[Any]) -> None:
        """Fig. 3.2 references, each kind labelled once: linear frequencies (thick) and
        subharmonics w_j / k (thin), coloured by mode from the palette that leaves out the
        stability red and the Neimark-Sacker green (:mod:`nsm_continuation.figures.styles`);
        for g > 0 the flat (linear, contact-free) part of each mode up to its linear grazing
        energy (for g < 0 there is none, Prop. 7.1); for g = 0 the discrete spectrum (roots of
        w_N, Prop. 7.2) found on ``branches``."""
        from nsm_continuation.figures.styles import palette_colour

        lo, hi = x_range
        lo, hi = lo - 0.02 * (hi - lo), hi + 0.02 * (hi - lo)
        kmax = self.SUBHARMONIC_KMAX
        names = {1: r"linear $\omega_j$ (colour = mode $j$)",
                 2: r"subharmonics $\omega_j/k$, $k \leq$" + f" {kmax}",
                 3: "linear (flat) part of a mode, up to its grazing energy"}
        for j, w in enumerate(self.problem.omega):
            colour = palette_colour(j)
            for k in range(1, kmax + 1):
                if lo <= w / k <= hi:
                    ax.axvline(w / k, color=colour, lw=1.6 if k == 1 else 0.5,
                               alpha=0.8 if k == 1 else 0.5, zorder=1,
                               label=names.pop(min(k, 2), "_nolegend_"))
            # g < 0: no contact-free (linear) orbit exists, u_c = 0 is beyond the wall
            # (sec. 7.1: the spectrum is not connected to the linear one)
            if lo <= w <= hi and self.problem.g > 0.0:
                ax.plot([w, w], [1e-300, self.problem.grazing_energy(j)], color=colour,
                        lw=3.2, solid_capstyle="butt", zorder=4,
                        label=names.pop(3, "_nolegend_"))
        if self.problem.g == 0.0:
            label = r"roots of $w_N$ (g = 0 spectrum)"
            for T in [s["T"] for s in self.problem.static_grazing_spectrum(branches)]:
                w = 2 * np.pi / T
                if lo <= w <= hi:
                    ax.axvline(w, color="tab:green", lw=1.8, ls="--", zorder=2, label=label)
                    label = "_nolegend_"

    def report_extras(self, branches: list[Any]) -> dict[str, Any]:
        out: dict[str, Any] = {
            "linear_grazing_energies": [float(self.problem.grazing_energy(j))
                                        if self.problem.g != 0 else 0.0
                                        for j in range(self.problem.N)]}
        graz = []
        for br in branches:
            for ev in br.events:
                if ev.kind == "grazing" and ev.data.get("tests") == ["clearance"]:
                    graz.append({"branch": br.id, "T": ev.point.derived["T"],
                                 "omega": ev.point.derived["omega"],
                                 "energy": ev.point.derived["energy"],
                                 "admissible_before": ev.data.get("admissible_before")})
        if graz:
            out["nonlinear_grazing_orbits"] = graz
        if self.problem.g == 0.0:
            out["static_grazing_spectrum"] = self.problem.static_grazing_spectrum(branches)
        return out

    def extra_plots(self, out_dir: Any, branches: list[Any],
                    window: tuple[float | None, float | None]) -> list[str]:
        """Fig. 3.1: ``w_N(T)`` with its poles ``k T_j`` (vertical lines coloured by mode,
        thick for ``k = 1``) and its zeros; the curve is broken at every pole (it goes to
        +-infinity there: no segment joins the two sides)."""
        from nsm_continuation.figures.kit import new_figure, save
        from nsm_continuation.figures.styles import palette_colour

        lo, hi = window
        lo = lo if lo is not None else 0.05 * self.problem.T_lin[-1]
        hi = hi if hi is not None else 1.2 * self.problem.T_lin[0]
        kmax = self.SUBHARMONIC_KMAX
        poles = self.problem.poles(lo, hi, kmax)
        every = [t for t, _, _ in self.problem.poles(lo, hi, 10**6)]
        T = np.union1d(np.linspace(lo, hi, 20000), every)
        wn = self.problem.w_N(T)
        wn[np.isin(T, every)] = np.nan  # the curve is broken at each pole
        fig, ax = new_figure(figsize=(10, 4.8))
        ax.plot(T, wn, color="k", lw=1.0, zorder=3, label=r"$w_N(T)$")
        names = {1: r"pole $T_j$ (linear period; colour = mode $j$)",
                 2: r"pole $k T_j$, $2 \leq k \leq$" + f" {kmax}"}
        for Tp, j, k in poles:
            ax.axvline(Tp, color=palette_colour(j), lw=1.4 if k == 1 else 0.6, alpha=0.8,
                       zorder=1, label=names.pop(min(k, 2), "_nolegend_"))
        zeros = self.problem.zeros_of_w_N(lo, hi)
        if zeros.size:
            ax.plot(zeros, np.zeros_like(zeros), "o", color="tab:green", ms=4, zorder=4,
                    label=r"zeros of $w_N$")
        ax.axhline(0, color="0.5", lw=0.6)
        finite = np.abs(wn[np.isfinite(wn)])
        top = 8.0 * float(np.median(finite)) if finite.size else 1.0
        ax.set_ylim(-top, top)
        ax.set_xlim(lo, hi)
        ax.set_xlabel("period $T$ [s]")
        ax.set_ylabel(r"$w_N(T) = \sum_j a_j \cot(\omega_j T/2)/\omega_j$")
        ax.set_title(r"$w_N$ against the period (Fig. 3.1); the curve leaves the axes at "
                     r"its poles", fontsize=10)
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
        ax.grid(alpha=0.25)
        fig.tight_layout()
        save(fig, Path(out_dir) / "w_N.png")
        return ["w_N.png"]
