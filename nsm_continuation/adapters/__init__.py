"""Adapters that hand an :class:`~nsm_continuation.core.problem.Problem` to other continuation
toolkits.

Each adapter lives in its own module and imports its toolkit lazily, so that ``nsm_continuation``
itself never depends on it:

* :mod:`nsm_continuation.adapters.pycont`: `pycont-lite <https://pypi.org/project/pycont-lite/>`_
  (``import pycont``), a matrix-free pseudo-arclength continuation code working on
  ``G(u, p) = 0``. Install with ``pip install nsm-continuation[pycont]``.
"""
