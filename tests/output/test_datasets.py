"""A run as data (:mod:`nsm_continuation.output.datasets`): booleans as booleans in what
``nsm.load`` returns (the CSV files unchanged), the events as a pandas DataFrame, the run as an
xarray Dataset written to netCDF and read back equal, and one ``ImportError`` line naming the
extra where pandas or xarray is missing.

The oracle is the run in memory: each case is computed, saved (:meth:`Result.save`), read back
(:func:`nsm.load`), and what the loaded run exports is compared with the points and events of
the computed run (:class:`~nsm_continuation.core.records.Point` fields, the event records of
``report.json``). The tests that need pandas or xarray are skipped with one line when the
``xarray`` extra is not installed (the ``test`` extra installs it)."""

from __future__ import annotations

import csv
import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

import nsm_continuation as nsm

#: the chain near omega_1 (its first point has no multipliers: a missing stability), and the
#: impact oscillator grown into a diagram whose switched branches are period-2 orbits
#: (problems of their own)
CASES = {
    "chain": ("ndof_default", {"continuation.max_points": 30, "output.plots": False}),
    "diagram": ("impact_oscillator_period_doubling", {
        "output.plots": False, "continuation.max_points": 30,
        "analysis.branch_switching": {"kinds": ["period_doubling"], "depth": 1,
                                      "max_points": 8}}),
}

NO_XARRAY = importlib.util.find_spec("xarray") is None
NO_PANDAS = importlib.util.find_spec("pandas") is None
NO_H5 = any(importlib.util.find_spec(m) is None for m in ("h5netcdf", "h5py"))


@pytest.fixture(scope="module", params=sorted(CASES))
def runs(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
         ) -> tuple[nsm.Result, nsm.Result, Path]:
    """``(the run in memory, the run read back, its folder)``."""
    name, over = CASES[request.param]
    fresh = nsm.run(name, over)
    folder = fresh.save(tmp_path_factory.mktemp(request.param) / "run", plots=False)
    return fresh, nsm.load(folder), folder


def _by_modulus(m: np.ndarray) -> np.ndarray:
    return m[np.argsort(-np.abs(m), kind="stable")]


def test_booleans_are_booleans_and_the_csv_files_unchanged(runs) -> None:
    fresh, loaded, folder = runs
    for a, b in zip(fresh.branches, loaded.branches, strict=True):
        if not len(a):
            continue
        for res_b in (a, b):
            adm, stab = res_b["admissible"], res_b["stable"]
            assert adm.dtype == bool and stab.dtype == bool
            assert adm.tolist() == [p.admissible for p in a.raw.points]
            missing = [p.stable is None for p in a.raw.points]
            assert np.ma.getmaskarray(stab).tolist() == missing
            assert [bool(s) for s, m in zip(np.ma.getdata(stab), missing, strict=True)
                    if not m] == [p.stable for p in a.raw.points if p.stable is not None]
        with open(folder / f"branch_{a.id}.csv", newline="", encoding="utf-8") as fh:
            rows = list(csv.DictReader(fh))
        assert {r["admissible"] for r in rows} <= {"0", "1"}
        assert [r["stable"] for r in rows] == ["" if p.stable is None else str(int(p.stable))
                                                for p in a.raw.points]
    assert any(p.stable is None for br in fresh.branches for p in br.raw.points) \
        or any(p.stable is False for br in fresh.branches for p in br.raw.points)


@pytest.mark.skipif(NO_PANDAS, reason="pandas not installed (pip install .[xarray])")
def test_events_frame_is_the_events(runs) -> None:
    fresh, loaded, _ = runs
    df = loaded.events_frame()
    events = fresh.events
    assert len(df) == len(events) > 2
    name = fresh.case.continuation.parameter or fresh.problem.parameter
    assert df["kind"].tolist() == [e.kind for e in events]
    assert df["branch"].tolist() == [e.branch for e in events]
    assert df["detail"].tolist() == [e.detail for e in events]
    for i, e in enumerate(events):
        variables = list(fresh.run_result.branch_problems.get(
            e.branch, fresh.problem).variables)
        assert df[name].iloc[i] == e.point.value(name, variables)
        assert df["s"].iloc[i] == e.point.s and df["admissible"].iloc[i] == e.point.admissible
        if e.record["stable"] is None:
            assert df["stable"].isna().iloc[i]
        else:
            assert bool(df["stable"].iloc[i]) == e.record["stable"]
        rec = np.array([complex(a, b) for a, b in e.record["multipliers"]], dtype=complex)
        assert np.array_equal(df["multipliers"].iloc[i], rec)
    assert str(df["stable"].dtype) == "boolean" and df["admissible"].dtype == bool


def _column(ds, branch_id: int, name: str) -> np.ndarray:
    return ds[name].values[ds["branch"].values == branch_id]


@pytest.mark.skipif(NO_XARRAY, reason="xarray not installed (pip install .[xarray])")
@pytest.mark.parametrize("engine", ["h5netcdf", "scipy"])
def test_load_to_xarray_to_netcdf_and_back(runs, engine: str, tmp_path: Path) -> None:
    if engine == "h5netcdf" and NO_H5:
        pytest.skip("h5netcdf/h5py not installed (pip install .[xarray])")
    import xarray as xr

    fresh, loaded, folder = runs
    ds = loaded.to_xarray()
    computed = fresh.to_xarray()
    assert ds.attrs["source"] == str(folder) and "source" not in computed.attrs
    computed.attrs["source"] = str(folder)
    xr.testing.assert_identical(computed, ds)  # the run read back exports the run itself
    for br in fresh.branches:
        pts = br.raw.points
        variables = list(fresh.run_result.branch_problems.get(br.id, fresh.problem).variables)
        assert _column(ds, br.id, "row").tolist() == list(range(len(pts)))
        y = _column(ds, br.id, "y")
        cols = [list(ds["unknown"].values).index(v) for v in variables]
        assert np.array_equal(y[:, cols], np.array([p.y for p in pts]).reshape(len(pts), -1))
        mult = _column(ds, br.id, "multipliers")
        for p, row in zip(pts, mult, strict=True):
            n = 0 if p.multipliers is None else p.multipliers.size
            if n:
                assert np.array_equal(row[:n], _by_modulus(p.multipliers))
            assert np.isnan(row[n:]).all()
        for c in br.column_names:
            if c.startswith(("y_", "mu")) or c == "signature":
                continue
            expected = np.ma.MaskedArray(br[c]).astype(float).filled(np.nan)
            np.testing.assert_array_equal(_column(ds, br.id, c), expected, err_msg=c)
    events = fresh.events
    assert ds["event_kind"].values.tolist() == [e.kind for e in events]
    assert ds["event_branch"].values.tolist() == [e.branch for e in events]
    unknowns = list(ds["unknown"].values)
    for e, y, m in zip(events, ds["event_y"].values, ds["event_multipliers"].values,
                       strict=True):
        variables = fresh.run_result.branch_problems.get(e.branch, fresh.problem).variables
        assert np.array_equal(y[[unknowns.index(v) for v in variables]], e.point.y)
        rec = np.array([complex(a, b) for a, b in e.record["multipliers"]], dtype=complex)
        assert np.array_equal(m[:rec.size], rec) and np.isnan(m[rec.size:]).all()
    assert ds["multipliers"].dtype == complex
    name = fresh.case.continuation.parameter or fresh.problem.parameter
    assert ds.attrs["continued_parameter"] == name and ds.attrs["problem"] == fresh.problem.name
    assert ds[name].attrs["long_name"] == fresh.problem.presentation.label(name)
    assert name in ds.coords and f"event_{name}" in ds.coords

    path = loaded.to_netcdf(tmp_path / "run.nc", engine=engine)
    back = nsm.open_netcdf(path)
    xr.testing.assert_identical(back, ds)
    if engine == "h5netcdf":  # netCDF-4 holds complex numbers: any xarray user reads them
        with xr.open_dataset(path) as plain:
            assert plain["multipliers"].dtype == complex
            assert np.array_equal(plain["multipliers"].values, ds["multipliers"].values,
                                  equal_nan=True)
    else:  # netCDF-3 does not: the real and imaginary parts
        with xr.open_dataset(path) as plain:
            assert "multipliers" not in plain and plain["multipliers_real"].dtype == float


def test_without_the_extra_one_import_error_line(runs, monkeypatch) -> None:
    _, loaded, _ = runs
    for module in ("pandas", "xarray"):
        monkeypatch.setitem(sys.modules, module, None)
    for call, name in ((loaded.events_frame, "Result.events_frame"),
                       (loaded.to_xarray, "Result.to_xarray"),
                       (lambda: loaded.to_netcdf("run.nc"), "Result.to_netcdf"),
                       (loaded.branches[0].to_frame, "BranchData.to_frame")):
        with pytest.raises(ImportError) as err:
            call()
        msg = str(err.value)
        assert "\n" not in msg and msg.startswith(name) and "nsm-continuation[xarray]" in msg


@pytest.mark.skipif(NO_XARRAY or NO_H5, reason="xarray/h5netcdf not installed "
                    "(pip install .[xarray])")
def test_a_run_without_multipliers_or_points_round_trips(tmp_path: Path) -> None:
    """Without stability no point has multipliers: no multiplier dimension, both engines
    round-trip. A run whose only start failed has no point and no event: both engines
    round-trip it too (netCDF-3 cannot hold an empty dimension: its variables are described
    in an attribute and restored)."""
    import xarray as xr

    small = {"name": "small", "problem": "ndof_impact",
             "parameters": {"chain": {"dofs": 2, "mass": 1.0, "stiffness": 1.0}, "gap": 1.0},
             "start": {"mode": 1}, "output": {"plots": False, "progress": False},
             "continuation": {"parameter": "omega", "min": 0.5, "max": 2.0, "max_points": 8},
             "analysis": {"stability": False}}
    res = nsm.run(small)
    ds = res.to_xarray()
    assert "multipliers" not in ds and "multiplier" not in ds.sizes
    assert ds.sizes["point"] == len(res.branches[0]) > 0
    assert np.isnan(ds["stable"].values).all()  # no multipliers: no stability
    for engine in ("h5netcdf", "scipy"):
        back = nsm.open_netcdf(res.to_netcdf(tmp_path / f"{engine}.nc", engine=engine))
        xr.testing.assert_identical(back, ds)
    # the chain with frequencies in the ratio 3: its start fails (a singular Jacobian)
    failed = nsm.run({**small, "parameters": {"M": [[1, 0], [0, 1]], "K": [[5, -4], [-4, 5]],
                                              "gap": 1.0}})
    assert [len(b) for b in failed.branches] == [0]
    ds = failed.to_xarray()
    assert ds.sizes["point"] == 0 == ds.sizes["event"]
    assert list(ds["unknown"].values) == failed.problem.variables
    for engine in ("h5netcdf", "scipy"):
        back = nsm.open_netcdf(failed.to_netcdf(tmp_path / f"f_{engine}.nc", engine=engine))
        xr.testing.assert_identical(back, ds)


@pytest.mark.skipif(NO_XARRAY or NO_H5 or importlib.util.find_spec("dask") is None,
                    reason="xarray/h5netcdf/dask not installed")
def test_netcdf_files_do_not_depend_on_the_sessions_dask_scheduler(tmp_path: Path) -> None:
    """A session left with Dask's distributed scheduler and no client (e.g. after a run on a
    cluster whose scheduler was lost: xarray then failed every write with "Requested
    dask.distributed scheduler but no Client active") still writes and reads a run."""
    import dask
    import xarray as xr

    small = {"name": "small", "problem": "ndof_impact",
             "parameters": {"chain": {"dofs": 2, "mass": 1.0, "stiffness": 1.0}, "gap": 1.0},
             "start": {"mode": 1}, "output": {"plots": False, "progress": False},
             "continuation": {"parameter": "omega", "min": 0.5, "max": 2.0, "max_points": 5}}
    res = nsm.run(small)
    ds = res.to_xarray()
    with dask.config.set(scheduler="dask.distributed"):
        for engine in ("h5netcdf", "scipy"):
            back = nsm.open_netcdf(res.to_netcdf(tmp_path / f"{engine}.nc", engine=engine))
            xr.testing.assert_identical(back, ds)
