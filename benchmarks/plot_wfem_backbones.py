"""Figs. 5-7 of Yoong, Thorin, Legrand (2017) in one chart: main backbones for g0 > 0, = 0, < 0.

Runs the three bundled cases ``yaml_cases/wfem_fig5_6_backbones_gap_*.yaml`` in process (N = 1000)
and overlays them (left: [omega_1, Omega_1] and [omega_2, Omega_2], normalised energy; right:
Fig. 7, the first backbone for several gaps, absolute energy, showing the branches approach the
g0 = 0 vertical line as g0 -> 0). Writes ``docs/wfem_fig5_7_backbones.png``.

    python benchmarks/plot_wfem_backbones.py
"""

from __future__ import annotations

import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from nsm_continuation.problems.bar.continuum_orbits import main_backbone  # noqa: E402

import nsm_continuation as nsm  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
#: colours of the gaps (the package's palette: no stability red, no Neimark-Sacker green)
COLORS = {"positive": "tab:blue", "zero": "k", "negative": "tab:orange"}
LABELS = {"positive": r"$g_0 = 10^{-3}$", "zero": r"$g_0 = 0$ (vertical: energy free)",
          "negative": r"$g_0 = -10^{-3}$"}


def branches(path: Path, overrides: list[str] | None = None):
    t0 = time.perf_counter()
    res = nsm.run(path, [*(overrides or []), "output.plots=false", "output.progress=false"])
    return res.run_result, time.perf_counter() - t0


def main() -> None:
    fig, (ax, ax7) = plt.subplots(1, 2, figsize=(13, 5))
    for gap in ("positive", "zero", "negative"):
        res, dt = branches(ROOT / f"yaml_cases/wfem_fig5_6_backbones_gap_{gap}.yaml")
        print(f"gap {gap}: {sum(b.n_points for b in res.branches)} points in {dt:.2f} s")
        label = LABELS[gap]
        for br in res.branches:
            x = [p.derived["omega_ratio"] for p in br.points]
            y = [p.derived["energy_ratio"] for p in br.points]
            if gap == "zero":
                ax.axvline(x[0], color="k", lw=2, label=label)
            else:
                ax.plot(x, y, ".-", color=COLORS[gap], ms=2, lw=1.2, label=label)
            label = "_nolegend_"
        if gap != "zero":  # the continuum limit in closed form (sec. 6.1), dashed over them
            for k in (1, 2):
                xb, yb = main_backbone(k, 1.0 if gap == "positive" else -1.0)
                ax.plot(xb, yb, ls=(0, (4, 3)), color="0.2", lw=0.9,
                        label="continuum limit (closed form, sec. 6.1)"
                        if (gap, k) == ("positive", 1) else "_nolegend_")
    for k, lab in ((1, r"$\omega_1$"), (2, r"$\Omega_1$"), (3, r"$\omega_2$"), (4, r"$\Omega_2$")):
        ax.axvline(k, ls=":", color="0.5", lw=0.8)
        ax.text(k + 0.02, 0.6, lab, ha="left", fontsize=9)
    ax.set_yscale("log")
    ax.set_ylim(0.5, 1e3)
    ax.set_xlabel(r"frequency $\omega/\omega_1$ (eq. 13)")
    ax.set_ylabel(r"energy $E/E_{ref}$ (eq. 14)")
    ax.set_title("Figs. 5-6: main backbones, N = 1000")
    ax.legend(fontsize=7, loc="upper center")
    for g0 in (1e-2, 3e-3, 1e-3, -1e-3, -3e-3, -1e-2):
        res, _ = branches(ROOT / "yaml_cases/wfem_fig5_6_backbones_gap_positive.yaml",
                          [f"parameters.gap={g0}", "parameters.cells=400",
                           "start=[{branch: main, mode: 1}]", "continuation.max=2.0",
                           "continuation.max_energy=1e6"])
        for br in res.branches:
            x = [p.derived["omega_ratio"] for p in br.points]
            y = [p.derived["energy"] for p in br.points]
            ax7.plot(x, y, "-", color=COLORS["positive" if g0 > 0 else "negative"],
                     alpha=0.35 + 0.2 * abs(round(1e3 * g0)) / 10, label=f"g0 = {g0:g}")
    ax7.axvline(4 / 3, color="k", lw=2, label="g0 = 0")
    ax7.set_yscale("log")
    ax7.set_xlabel(r"frequency $\omega/\omega_1$ (eq. 13)")
    ax7.set_ylabel("energy $E$ (not normalised)")
    ax7.set_title("Fig. 7: first backbone vs g0 (N = 400)")
    ax7.legend(fontsize=7)
    fig.tight_layout()
    out = ROOT / "docs/wfem_fig5_7_backbones.png"
    fig.savefig(out, dpi=120)
    print("wrote", out)


if __name__ == "__main__":
    main()
