"""Test-only oracles: independent derivations the tests compare the package with (not part of
the installed package). ``pendulum_lagrange``: the Euler-Lagrange derivation of the double
pendulum of Nordmark & Piiroinen (2009), sec. 6, vs the printed eq. (53); ``pendulum_equilibria``:
the sticking saddle of sec. 6.3 and its eigenvalues from a reduced 1-dof Lagrangian;
``bouncing_ball``: ``D_N`` of eq. (50) rebuilt from the saltation matrix (43); ``wfem_bar``:
the ring basis, the integrated contact-end displacement, the exact falling bar and the modal
steady state of the forced linear bar; ``hybrid_codim1``: the start of a grazing curve from a
grazing orbit; ``scaled_chain``: the chain of the paper's scaling (2.17) and its closed-form
orbit (4.2); ``trig_sum``: a sum of sinusoids and the roots of its derivative; ``two_wall``: the
symmetric two-impact orbits of a two-sided impact oscillator and of an impact damper in closed
form, their multipliers and bifurcations, and an event-driven simulator of both. Imported by the
tests as ``oracles.<module>`` (``tests/conftest.py`` puts ``tests/`` on ``sys.path``)."""
