"""The starts of ``wfem_bar`` (Yoong, Thorin, Legrand 2017, sec. 6) and their seeds.

A start is one of the YAML start kinds: the main backbone of a mode (sec. 6.1), a subharmonic
backbone (sec. 6.2, from eq. 15), a scan of the window (every physical admissible orbit seeds a
branch, Figs. 12 and 16) or an explicit lattice node (eq. 12 or 18). The seed search
(:class:`WfemBarSeeds`) turns each into the first physical orbit of its branch: near the start
frequency of a backbone (omega_k for g0 > 0, Omega_k for g0 < 0, the asymptote of sec. 6.1 for
g0 = 0), at the node, or among the scanned orbits.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

import numpy as np
from nsm_continuation.problems.bar.continuum_orbits import main_asymptote, subharmonic_start
from nsm_continuation.problems.bar.wfem_lattice import (
    classify,
    grazing_representative,
    profile_jumps,
    solve_node,
)
from pydantic import BaseModel, Discriminator, Field, Tag

from nsm_continuation.core.lattice import LatticeSeed
from nsm_continuation.core.preflight import STRICT, exactly


class MainStart(BaseModel):
    """The main backbone of mode k (section 6.1)."""

    model_config = STRICT
    #: the main backbone (from ``omega_k`` if g0 > 0, from ``Omega_k`` if g0 < 0, the
    #: vertical line if g0 = 0)
    branch: Literal["main"]
    #: the mode ``k``
    mode: Annotated[int, Field(ge=1, le=50)] = 1


class SubharmonicStart(BaseModel):
    """The n-th subharmonic backbone of mode k (g0 > 0), starting near eq. (15)."""

    model_config = STRICT
    #: a subharmonic backbone (g0 > 0)
    branch: Literal["subharmonic"]
    #: the mode ``k``
    mode: Annotated[int, Field(ge=1, le=50)] = 1
    #: the subharmonic's order ``n`` (eq. 15)
    n: Annotated[int, Field(ge=1, le=50)] = 1


class ScanStart(BaseModel):
    """Every physical admissible orbit in the window seeds a branch (Fig. 12, 16)."""

    model_config = STRICT
    #: ``true``: scan the lattice nodes of every period in the window
    scan: Annotated[Literal[True], exactly(True)]
    #: at most this many seeds (fewest profile jumps, then lowest energy); default every one
    max_seeds: Annotated[int, Field(ge=1)] | None = None


class NodeStart(BaseModel):
    """An explicit lattice node (m, p) or (m, p, k, l) (eq. 18)."""

    model_config = STRICT
    #: ``[m, p]`` (eq. 12) or ``[m, p, k, l]`` (eq. 18): the phase lengths, in time steps
    node: list[Annotated[int, Field(ge=1)]]
    #: which way along ``continuation.parameter`` the branch is followed
    direction: Literal["both", "increase", "decrease"] = "both"


def _start_kind(v: Any) -> str:
    """Which start model a mapping is (by its ``branch`` / ``scan`` / ``node`` key), so an error
    names the key of that model only; capitalised tags are left out of error locations."""
    if isinstance(v, dict):
        if "node" in v:
            return "Node"
        if "scan" in v:
            return "Scan"
        return "Subharmonic" if v.get("branch") == "subharmonic" else "Main"
    return {SubharmonicStart: "Subharmonic", ScanStart: "Scan", NodeStart: "Node"}.get(
        type(v), "Main")


OneStart = Annotated[Annotated[MainStart, Tag("Main")]
                     | Annotated[SubharmonicStart, Tag("Subharmonic")]
                     | Annotated[ScanStart, Tag("Scan")] | Annotated[NodeStart, Tag("Node")],
                     Discriminator(_start_kind)]


class WfemBarSeeds:
    """The seed search of :class:`problems.bar.wfem_bar.WfemBarProblem` (a mixin placed before
    :class:`~nsm_continuation.core.lattice.LatticeProblem` in its bases): the first physical
    orbit of each start's branch (module docstring), found among the problem's node solutions
    (:meth:`problems.bar.wfem_nodes.WfemLatticeNodes.physical`)."""

    def lattice_seeds(self, start: Any, window: tuple[float | None, float | None],
                      energy_cap: float | None = None) -> list[LatticeSeed]:
        spec = self.start_adapter.validate_python(start) if not isinstance(
            start, BaseModel) else start
        if isinstance(spec, list):
            return [seed for one in spec
                    for seed in self.lattice_seeds(one, window, energy_cap)]
        if isinstance(spec, ScanStart):  # depends on energy_cap: never cached
            return self._lattice_seeds(spec, window, energy_cap)
        key = (spec.model_dump_json(), window)
        if key not in self._seed_cache:  # the preflight's seed search is reused by the run
            self._seed_cache[key] = self._lattice_seeds(spec, window)
        return list(self._seed_cache[key])

    def _lattice_seeds(self, spec: BaseModel, window: tuple[float | None, float | None],
                       energy_cap: float | None = None) -> list[LatticeSeed]:
        md = self.model
        if isinstance(spec, NodeStart):
            if len(spec.node) not in (2, 4):
                raise ValueError(f"start.node: {spec.node} has {len(spec.node)} entries; a "
                                 "lattice node is [m, p] (eq. 12) or [m, p, k, l] (eq. 18)")
            sols = self.physical(tuple(spec.node))
            if not sols:
                self._refuse_strained([tuple(spec.node)], f"at node {spec.node}")
                raise ValueError(f"node {spec.node}: no physical admissible orbit")
            d = {"both": 0, "increase": 1, "decrease": -1}[spec.direction]
            return [LatticeSeed(sols[0], f"node {tuple(spec.node)}", d)]
        if isinstance(spec, ScanStart):
            sols = self.scan_window(window)
            sols.sort(key=lambda s: (profile_jumps(s.w0), s.energy))
            cap = energy_cap
            if cap is not None:  # seeds above the energy bound would give one-point branches
                sols = [s for s in sols if s.energy / md.energy_ref <= cap]
            if spec.max_seeds is not None and len(sols) > spec.max_seeds:
                note = (f"start.scan: {len(sols)} physical orbits in the window (below "
                        f"continuation.max_energy), only the first "
                        f"max_seeds = {spec.max_seeds} (fewest profile jumps, then lowest "
                        "energy) seed branches; a branch none of them lies on is not computed "
                        "(raise start.max_seeds: a seed on a branch already computed costs "
                        "one lookup)")
                if note not in self._seed_notes:
                    self._seed_notes.append(note)
            return [LatticeSeed(s, f"scan seed (m, p) = {s.counts}", 0)
                    for s in sols[:spec.max_seeds]]
        k = spec.mode
        N = md.N
        if isinstance(spec, SubharmonicStart):
            if md.g0 <= 0:
                raise ValueError("branch: subharmonic starts are defined for gap > 0 (eq. 15)")
            r0 = subharmonic_start(k, spec.n)
            return self._first_seed(int(np.floor(4 * N / r0)) - 1, -1, 1,
                                    f"subharmonic n = {spec.n} of mode {k} (eq. 15: "
                                    f"{r0:.4f} omega_1)")
        if md.g0 == 0:
            return self._grazing_seeds(k)
        if md.g0 > 0:  # hardening from omega_k = (2k - 1) omega_1: periods just below T_k
            return self._first_seed(int(np.floor(4 * N / (2 * k - 1))) - 1, -1, 1,
                                    f"main backbone, mode {k}")
        # softening from Omega_k = 2k omega_1: periods just above
        return self._first_seed(int(np.ceil(2 * N / k)) + 1, 1, -1, f"main backbone, mode {k}")

    def _first_seed(self, M0: int, dM: int, direction: int, label: str) -> list[LatticeSeed]:
        """First physical orbit met from period M0 on (step dM), fewest jumps then lowest energy.

        Near the start of a backbone one phase is short (contact for g0 > 0, free for g0 < 0),
        so only nodes whose short phase is at most 5 % of the period are tried.
        """
        N = self.model.N
        tried: list[tuple[int, int]] = []
        for j in range(max(4, int(0.1 * N))):
            M = M0 + dM * j
            short = max(2, int(0.05 * M))
            pairs = ([(M - p, p) for p in range(1, short)] if direction > 0
                     else [(m, M - m) for m in range(1, short)])
            tried += pairs
            cands = [s for c in pairs for s in self.physical(c)]
            if cands:
                best = min(cands, key=lambda s: (profile_jumps(s.w0), s.energy))
                return [LatticeSeed(best, label, direction)]
        self._refuse_strained(tried, f"near the start of the {label}")
        raise ValueError(f"no physical orbit found near the start of the {label} (N = {N}); "
                         "increase cells")

    def _refuse_strained(self, nodes: list[tuple[int, ...]], where: str) -> None:
        """Where no seed was found because the orbits at ``nodes`` fail COND3 alone (strain
        ``|sigma| / E`` above 1: the gap is large against the bar's length), say so, naming
        the gap and the gap below which these orbits exist (they scale with it)."""
        md = self.model
        strains = [float(np.abs(sol.w0).max()) / md.E for c in nodes[:400]
                   for status, sol in [solve_node(md, c)]
                   if status == "inadmissible: cond3_strain" and sol is not None]
        if strains:
            s = min(strains)
            raise ValueError(
                f"parameters.gap: at |gap| = {abs(md.g0):g} the orbits {where} strain the bar "
                f"beyond COND3 (strain |sigma| / E = {s:.4g} > 1; L = "
                f"{md.L:g}): they scale with the gap, so they exist for |gap| below "
                f"{abs(md.g0) / s:.4g}")

    def _grazing_seeds(self, k: int) -> list[LatticeSeed]:
        """g0 = 0: the vertical backbone of mode k at its asymptote (section 6.1).

        Nodes at the asymptote's period are tried in order of closeness of the contact fraction
        to 1/(2k + 1) (1/3 for mode 1: contact L/c in 3L/c; 1/5 for mode 2: L/(4c) in 5L/(4c)).
        """
        N = self.model.N
        M = int(round(4 * N / main_asymptote(k)))
        for p in sorted(range(1, M), key=lambda p: abs(p - M / (2 * k + 1))):
            sol = grazing_representative(self.model, (M - p, p))
            if sol is not None and classify(sol) == "physical":
                return [LatticeSeed(sol, f"main backbone, mode {k} (g0 = 0)", 1)]
        raise ValueError(f"g0 = 0, mode {k}: no admissible node at M = {M} "
                         f"(4N/M = {4 * N / M:.6f} omega_1)")


__all__ = ["MainStart", "NodeStart", "OneStart", "ScanStart", "SubharmonicStart", "WfemBarSeeds"]
