"""The elastic bar clamped at x = 0 with a unilateral contact at x = L.

Yoong, Thorin, Legrand (2017), *Nonsmooth modal analysis of an elastic bar subject to a unilateral
contact constraint* (``../shared/papers/001_e67577b12e22dc73.txt``):

* problems: :mod:`.wfem_bar` (``wfem_bar``: WFEM nonsmooth modes on the (m, p) lattice) and
  :mod:`.continuum` (``bar_continuum``: their exact continuum limit, pseudo-arclength);
* models: :mod:`.wfem_operators` (signed-permutation operators), :mod:`.wfem_lattice` (kernel,
  admissibility, filter), :mod:`.wfem_simulation` (time stepping, forced responses) and the exact
  bouncing bar of Table 1, :mod:`.bouncing_bar_exact`;
* analyses: :mod:`.wfem_stability` (orbital stability by time stepping);
* figures: :mod:`.plots` (orbit reconstructions), :mod:`.plots_forced` (forced responses).
"""
