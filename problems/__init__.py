"""Systems from the papers, one sub-package per family (installed as ``nsm_continuation.problems``).

* :mod:`.chain`: the N-dof chain impacting a rigid wall (Legrand, Junca, Heng 2017);
* :mod:`.bar`: the elastic bar with a unilateral contact, WFEM and its continuum limit
  (Yoong, Thorin, Legrand 2017);
* :mod:`.impacting`: hybrid impacting systems with chattering and sticking (Nordmark & Piiroinen
  2009).

Each family holds its problems (registered by entry points in ``pyproject.toml``), its models,
its analyses and its figures; oracles used only by the tests live in ``tests/``.
"""
