"""Short point lists of an adaptive plane computed by the client (study.drive,
AdaptivePlan.compute_here): the same map as when the cluster computes every list,
and a list that fails in the client goes to the cluster instead.
"""

from __future__ import annotations

import io
import re
from types import SimpleNamespace

import numpy as np
import pytest
import xarray as xr
from test_work_folder_faults import _kept_work

from study import Study, run_study
from study.adaptive import LOCAL_POINTS, AdaptivePlan
from study.drive import Driven, _Window

ADAPTIVE = """
[study]
name = "here"
fidelity = "fast"

[[scene]]
name = "s"
contact = "ground"
dof = 2
mode = "adaptive"
coarse_step = 8
verify_fraction = 0.01
r = {start = 0.1, stop = 2.4, num = 120}
beta = {start = 0.0, stop = 1.5, num = 60}
"""

KEYS = ("regime", "simulated", "verification", "converged", "stops_per_cycle", "period")


def _run(path, out, client) -> tuple[dict[str, np.ndarray], int, int]:
    log = io.StringIO()
    run_study(Study.from_toml(path), out, client=client, progress=False, stream=log)
    lists, here = (
        int(x) for x in re.search(r"(\d+) point lists computed \((\d+) by", log.getvalue()).groups()
    )
    with xr.open_dataset(out) as ds:
        return {k: ds[k].values for k in KEYS}, lists, here


@pytest.mark.cluster
def test_short_point_lists_computed_by_the_client_give_the_same_map(
    tmp_path, cluster_client, monkeypatch
):
    path = tmp_path / "here.toml"
    path.write_text(ADAPTIVE, encoding="utf-8")
    monkeypatch.setattr(AdaptivePlan, "tiles", False)  # tiles leave no short list here
    # the refinement's last lists here hold 20-50 points: a bound above them makes the
    # choice independent of the machine's speed (the rule for idle workers times them)
    monkeypatch.setattr(AdaptivePlan, "local_points", 64)
    got, lists, here = _run(path, tmp_path / "here.nc", cluster_client)
    assert 0 < here < lists  # the short ones only, the others on the cluster
    monkeypatch.setattr(AdaptivePlan, "local_points", 0)
    want, _, none = _run(path, tmp_path / "cluster.nc", cluster_client)
    assert none == 0
    for k in KEYS:  # the labels (hence the refinement) do not depend on where
        np.testing.assert_array_equal(got[k], want[k], err_msg=k)
    assert len(np.unique(want["regime"])) >= 3 and want["simulated"].mean() < 0.5


class _Plan:
    """A plan whose every unit is to be computed here, with a task no simulator knows."""

    def __init__(self) -> None:
        self.accepted: list = []

    def compute_here(self, unit) -> bool:
        return unit.n_points <= LOCAL_POINTS

    def task(self, unit) -> dict:
        return {"kind": "no such kind"}


def test_a_point_list_that_fails_in_the_client_goes_to_the_cluster():
    taken: list = []
    win = SimpleNamespace(done=Driven(), take=lambda *a: taken.append(a))
    plan, unit = _Plan(), SimpleNamespace(n_points=3, key="k")
    assert _Window.here(win, plan, unit) is False  # ValueError here: submitted instead
    assert not taken and win.done.here == 0
    big = SimpleNamespace(n_points=LOCAL_POINTS + 1, key="k")
    assert _Window.here(win, plan, big) is False  # too long: never tried here
    assert not taken


@pytest.mark.cluster
def test_the_file_holds_the_work_folder_values_with_its_encoding(
    tmp_path, cluster_client, monkeypatch
):
    """The result file (zlib level 1, no shuffle for an adaptive map: study.netcdf
    COMPRESSION) read back with xarray equals the result assembled in memory from the
    same work folder, every variable to the bit."""
    from study.chunks import plan
    from study.netcdf import result_tree, write_result
    from study.store import WorkDir

    study, out = _computed_not_written(tmp_path, cluster_client, monkeypatch)
    work = WorkDir(out)
    plans = plan(study)
    for p in plans:
        p.prepare(work)
    write_result(study, plans, work, out)
    memory = result_tree(study, plans, work).to_dataset()
    with xr.open_dataset(out) as ds:
        assert set(memory.data_vars) <= set(ds.data_vars)
        for name in memory.data_vars:
            np.testing.assert_array_equal(ds[name].values, memory[name].values, err_msg=name)
            assert ds[name].dtype == memory[name].dtype, name
        enc = ds["slip_amplitude"].encoding
        assert enc["zlib"] and enc["complevel"] == 1 and not enc["shuffle"]
        assert ds["regime"].encoding["complevel"] == 1
    work.remove()


@pytest.mark.cluster
def test_a_plane_never_saved_is_refined_again_from_its_point_lists(
    tmp_path, cluster_client, monkeypatch
):
    """The run's last plane is written from memory, not saved first (AdaptivePlan.keep
    saves it only when the run stops before the file is written). Without its file (a
    client killed during the write), the rerun answers the refinement from the saved
    point lists: no point list computed, the same file."""
    study, out = _computed_not_written(tmp_path, cluster_client, monkeypatch)
    work = tmp_path / "here.nc.work"
    planes = sorted(work.glob("*/*-plane-*.npz"))
    assert len(planes) == 1  # kept when the write did not happen
    want = {k: v for k, v in np.load(planes[0]).items() if not k.startswith("_")}
    planes[0].unlink()  # as if the client had been killed before keeping it
    log = io.StringIO()
    run_study(study, out, client=cluster_client, progress=False, stream=log)
    assert re.search(r" 0 point lists computed \(0 by the client\)", log.getvalue()), log.getvalue()
    assert not work.exists()
    with xr.open_dataset(out) as ds:
        for k in KEYS + ("slip_amplitude", "cycles"):
            np.testing.assert_array_equal(ds[k].values, want[k].T, err_msg=k)


def _computed_not_written(tmp_path, client, monkeypatch) -> tuple[Study, object]:
    """The study :data:`ADAPTIVE` computed to ``here.nc``, every unit saved in the work
    folder, the result file not written (Ctrl-C at its assembly; a clean run first)."""
    path, out = tmp_path / "here.toml", tmp_path / "here.nc"
    path.write_text(ADAPTIVE, encoding="utf-8")
    study = Study.from_toml(path)
    _kept_work(study, out, client, monkeypatch)
    return study, out
