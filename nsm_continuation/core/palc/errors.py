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


#: what a problem's hook may raise that ends a half-branch, never the run: any exception (a bug
#: in a hook, or a :class:`MonitorError`) and ``SystemExit`` (a hook that calls ``sys.exit``:
#: the process must not end with the plugin's exit code and no message)
HOOK_FAULTS = (Exception, SystemExit)


class MonitorError(RuntimeError):
    """A monitor of the problem gave what the engine cannot use (an admissibility test or a
    Floquet multiplier that is not finite): the problem's fault, named; the half-branch ends
    with this message."""


def check_finite(what: str, values: dict[str, float], where: str) -> None:
    """Raise :class:`MonitorError` naming the first value of ``values`` (a monitor's values by
    name, ``what`` saying which hook gave them) that is not a finite number."""
    for name, v in values.items():
        try:
            ok = bool(np.isfinite(v))
        except TypeError:
            ok = False
        if not ok:
            raise MonitorError(f"{what} {name!r} is {v!r} at {where}: not a finite number")


def describe_fault(exc: BaseException, problem: str = "") -> str:
    """The termination reason of a half-branch ended by a hook's fault (:data:`HOOK_FAULTS`)
    of the problem named ``problem``."""
    if isinstance(exc, SystemExit):
        who = f"problem {problem!r}" if problem else "the problem"
        return (f"{who} raised SystemExit({exc.code!r}) in a hook (sys.exit): a problem's "
                "hooks must raise an exception, not exit the process")
    if isinstance(exc, MonitorError):
        return str(exc)
    return f"internal error: {type(exc).__name__}: {exc}"


def describe_error(exc: BaseException) -> str:
    """The message of a problem's :class:`EvaluationError` (the real cause), or ``Type: msg``."""
    if isinstance(exc, EvaluationError) and str(exc):
        return str(exc)
    return f"{type(exc).__name__}: {exc}"


class RetryStep(Exception):
    """Raised while analysing a step whose result cannot be trusted (an event that cannot be
    located on the arc, a bound not reached): the step is retried with half its length."""
