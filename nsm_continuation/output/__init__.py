"""Where a run writes (never over a user's files), the files it writes, and its report."""

from typing import Any


def __getattr__(name: str) -> Any:
    from nsm_continuation._deprecated import forward

    return forward(__name__, name)
