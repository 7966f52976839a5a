"""YAML cases: the schema and its validation, restart specs, saved runs, the problem registry."""

from typing import Any


def __getattr__(name: str) -> Any:
    from nsm_continuation._deprecated import forward

    return forward(__name__, name)
