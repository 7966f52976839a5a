"""Runs of a validated case: one run (:mod:`.runner` over :mod:`.branches`), where its branches
are computed (:mod:`.execution`: here or on Dask), bifurcation diagrams as runs of runs
(:mod:`.diagrams`), the result in memory (:mod:`.result`) and its restart record."""
