"""Progress shown wherever it is asked for: tqdm's bar (text on a terminal; elsewhere
``tqdm.auto``, a widget in a Jupyter notebook, text without a TTY), else a plain line on
stderr. Used by the engines' runs (:mod:`nsm_continuation.runs.branches`: one tick a point)
and the brute-force diagrams (:mod:`nsm_continuation.hybrid.brute_force`: one tick a value).
Whether to show one at all is the caller's choice (the command line: only on a terminal)."""

from __future__ import annotations

import sys
import time
from typing import Any

#: the words of a plain line for tqdm's units
_UNIT_WORDS = {"pt": "points"}


class LineProgress:
    """A progress line on stderr where tqdm is not installed: ``name: n / total points``,
    rewritten at most twice a second, ended by a newline."""

    def __init__(self, desc: str, total: int, unit: str = "pt") -> None:
        self.desc, self.total, self.n, self.shown = desc, total, 0, 0.0
        self.words = _UNIT_WORDS.get(unit, f"{unit}s")

    def update(self, n: int) -> None:
        self.n += n
        if time.monotonic() - self.shown >= 0.5:
            self.shown = time.monotonic()
            sys.stderr.write(f"\r{self.desc}: {self.n} / {self.total} {self.words}")
            sys.stderr.flush()

    def set_postfix_str(self, text: str) -> None:
        """tqdm's note after the bar: not shown by the plain line."""

    def close(self) -> None:
        sys.stderr.write(f"\r{self.desc}: {self.n} {self.words}\n")
        sys.stderr.flush()


def progress_bar(desc: str, total: int, unit: str = "pt") -> Any:
    """A progress bar of ``total`` ``unit`` (module docstring), else a
    :class:`LineProgress`."""
    try:
        if sys.stderr.isatty():  # a terminal: the text bar (tqdm.auto would import IPython)
            from tqdm import tqdm
        else:
            from tqdm.auto import tqdm
    except ImportError:
        return LineProgress(desc, total, unit)
    # no monitor thread: a process without threads may draw its figures in a forked child
    # (nsm_continuation.figures.process)
    tqdm.monitor_interval = 0
    return tqdm(total=total, unit=unit, leave=False, desc=desc, disable=False)


__all__ = ["LineProgress", "progress_bar"]
