"""The elastic bar clamped at x = 0 with a unilateral contact at x = L.

Yoong, Thorin, Legrand (2017), *Nonsmooth modal analysis of an elastic bar subject to a unilateral
contact constraint* (``../shared/papers/001_e67577b12e22dc73.txt``):

* problems: :mod:`.wfem_bar` (``wfem_bar``: WFEM nonsmooth modes on the (m, p) lattice; its
  starts and seeds :mod:`.wfem_starts`, preflight :mod:`.wfem_preflight` and node store
  :mod:`.wfem_nodes`), :mod:`.continuum` (``bar_continuum``: their exact continuum limit,
  pseudo-arclength) and :mod:`.forced_response` (``wfem_forced_bar``: steady forced responses,
  section 7);
* presentation of the three problems (diagrams, CSV and report columns, extra figures):
  :mod:`.presentation`;
* models: :mod:`.wfem_operators` (signed-permutation operators), :mod:`.wfem_lattice` (kernel,
  admissibility, filter), :mod:`.wfem_stepping` (time stepping, Algorithm 2);
* closed forms: :mod:`.continuum_orbits` (the continuum orbits, their energy and the backbone
  frequencies), :mod:`.linear_forced` (linear forced responses), and the exact bouncing bar of
  Table 1, :mod:`.bouncing_bar_exact`;
* analyses: :mod:`.forced_steady_state` (steady forced responses by time stepping),
  :mod:`.wfem_stability` (orbital stability by time stepping); :mod:`.wfem_simulation`
  re-exports the names of the simulation modules;
* figures: :mod:`.plots` (orbit reconstructions), :mod:`.plots_forced` (forced responses).
"""
