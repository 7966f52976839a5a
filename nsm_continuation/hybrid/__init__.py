"""Impacting systems in general (Nordmark & Piiroinen 2009, paper 002).

* :mod:`.system` — the symbolic declaration (F, H, W or M, N, e) and everything CasADi derives from
  it: v, a, r, lambda, F', the chatter map Q, q, integrator steps with their exact Jacobians.
* :mod:`.simulate` — event-driven simulation with complete chattering (Table 1), with the
  sensitivities of the end state (the saltation-chained monodromy, eqs. (40), (43)).
* :mod:`.saltation` — the saltation matrix (43) and the chattering map's rank drop (sec. 4.4).
* :mod:`.shooting` — periodic orbits on a Poincaré section as a continuation Problem.
"""

from nsm_continuation.hybrid.system import CompiledHybrid, HybridDeclarationError, HybridSystem

__all__ = ["CompiledHybrid", "HybridDeclarationError", "HybridSystem"]
