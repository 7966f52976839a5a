"""Shared set-up of the test suite.

The tests live in folders named for the capability they check (``engine/``, ``floquet/``,
``chain/``, ``bar/``, ``hybrid/``, ``cases/``, ``runs/``, ``output/``, ``interface/``), none of
them a package. pytest imports this file first and puts its folder, ``tests/``, on ``sys.path``,
so every test imports the independent derivations as ``oracles.<module>``.
"""
