"""Impacting systems in general (Nordmark & Piiroinen 2009, paper 002).

* :mod:`.system` — the symbolic declaration (F, H, W or M, N, e) and everything CasADi derives from
  it: v, a, r, lambda, F', the chatter map Q, q, integrator steps with their exact Jacobians.
* :mod:`.tableaus` — the Runge-Kutta tableaus of the integrator steps.
* :mod:`.linear_flow` — the exact free flight of a system linear between events (modal flow,
  particular harmonic solution, closed-form Jacobian), detected from the declaration;
  :mod:`.modal_sums` its certified step lengths and extremes (exponential-trigonometric sums).
* :mod:`.simulate` — event-driven simulation with complete chattering (Table 1), with the
  sensitivities of the end state (the saltation-chained monodromy, eqs. (40), (43)), built from
  :mod:`.modes` (the discrete states and their watched functions), :mod:`.hermite` (crossings
  of the cubic Hermite interpolants on a step), :mod:`.transitions` (impacts, the chatter map,
  sticking, release) and :mod:`.sim_data` (options, events, results).
* :mod:`.saltation` — the saltation matrix (43) and the chattering map's rank drop (sec. 4.4).
* :mod:`.return_map` — the return map on a Poincaré section, its residual and exact Jacobian,
  the accuracy of its multipliers, and the shooting problem with the period prescribed.
* :mod:`.grazing` — continuation through a grazing (the discontinuity-map normal form, G1-G2).
* :mod:`.problem` — the return map as a continuation Problem (multipliers, events, charts);
  :mod:`.presentation` its axes, CSV columns, figures and report extras; :mod:`.homoclinic` the
  period law near a homoclinic orbit; :mod:`.orbit_trace` its orbits sampled in time.
* :mod:`.case` — the base class of impacting families read from YAML, with :mod:`.specs` (the
  ``integrator`` and ``start`` blocks), :mod:`.case_preflight` (checks before simulating) and
  :mod:`.case_period` (continuation in the period).
* :mod:`.codim1` — two-parameter continuation of grazings; :mod:`.brute_force` — brute-force
  bifurcation diagrams; :mod:`.equilibria` — equilibria on the sticking surface.
"""

from nsm_continuation.hybrid.system import CompiledHybrid, HybridDeclarationError, HybridSystem

__all__ = ["CompiledHybrid", "HybridDeclarationError", "HybridSystem"]
