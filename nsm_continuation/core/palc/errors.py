"""How a step of the continuation fails: errors of numerical origin (the step is retried
shorter, and the error's message ends the branch if it must) and the step whose events cannot be
trusted (:class:`RetryStep`)."""

from __future__ import annotations

import numpy as np

from nsm_continuation.core.problem import EvaluationError

#: errors of numerical origin (a problem that cannot evaluate at a point, linear algebra,
#: floating point): a step that meets one is retried smaller, like a failed Newton step, and the
#: error's message is the termination reason if the branch has to end. Any other exception is a
#: bug: it ends the half-branch (``internal error: ...``) and keeps the points computed so far.
NUMERICAL_ERRORS = (EvaluationError, np.linalg.LinAlgError, FloatingPointError, OverflowError,
                    ZeroDivisionError)


def describe_error(exc: BaseException) -> str:
    """The message of a problem's :class:`EvaluationError` (the real cause), or ``Type: msg``."""
    if isinstance(exc, EvaluationError) and str(exc):
        return str(exc)
    return f"{type(exc).__name__}: {exc}"


class RetryStep(Exception):
    """Raised while analysing a step whose result cannot be trusted (an event that cannot be
    located on the arc, a bound not reached): the step is retried with half its length."""
