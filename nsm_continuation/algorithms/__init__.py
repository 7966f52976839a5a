"""Continuation algorithms as objects: the contract (:mod:`.base`), the algorithms by name
(:mod:`.registry`: ``palc``, ``located_events``, ``lattice``, ``pycont``, ``sweep``), two-parameter
curves of located points (:mod:`.curves`) and branch switching (:mod:`.switching`)."""

from typing import Any


def __getattr__(name: str) -> Any:
    from nsm_continuation._deprecated import forward

    return forward(__name__, name)
