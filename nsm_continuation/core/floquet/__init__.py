"""Floquet multipliers: trivial multipliers removed and crossings classified
(:mod:`~nsm_continuation.core.floquet.deflation`), Krein signatures and their collisions
(:mod:`~nsm_continuation.core.floquet.krein`), and the multipliers of a low-rank update of a
normal map with their Krein definiteness (:mod:`~nsm_continuation.core.floquet.lowrank`, on the
secular equation of :mod:`~nsm_continuation.core.floquet.secular` solved by the Ehrlich-Aberth
iterations of :mod:`~nsm_continuation.core.floquet.aberth` and
:mod:`~nsm_continuation.core.floquet.pairs`).
"""

from nsm_continuation.core.floquet.aberth import refine_roots
from nsm_continuation.core.floquet.deflation import (
    CROSSING_COMPLEX,
    CROSSING_MINUS_ONE,
    CROSSING_PLUS_ONE,
    classify_crossing,
    classify_outside,
    count_outside,
    deflate_known_eigenvector,
    householder_basis,
    restrict_to_section,
)
from nsm_continuation.core.floquet.krein import (
    KREIN_DEFINITE,
    SEVERAL,
    KreinFloquetData,
    collision_distances,
    definite_sign,
    discriminant,
    krein_of,
    nearest_distances,
    signature_word,
    swap_paths,
)
from nsm_continuation.core.floquet.lowrank import krein_definiteness, low_rank_update_eigen

__all__ = [
    "CROSSING_COMPLEX",
    "CROSSING_MINUS_ONE",
    "CROSSING_PLUS_ONE",
    "KREIN_DEFINITE",
    "SEVERAL",
    "KreinFloquetData",
    "classify_crossing",
    "classify_outside",
    "collision_distances",
    "count_outside",
    "definite_sign",
    "deflate_known_eigenvector",
    "discriminant",
    "householder_basis",
    "krein_definiteness",
    "krein_of",
    "low_rank_update_eigen",
    "nearest_distances",
    "refine_roots",
    "restrict_to_section",
    "signature_word",
    "swap_paths",
]
