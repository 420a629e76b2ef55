"""The verification sample of an adaptive plane, drawn by a seeded priority per point.

* a point's priority depends on its index and the seed only, and is uniform;
* the sample holds the inferred points of priority below the fraction, at least
  the minimum (those of least priority): so the sample of fewer inferred points
  is the sample of more restricted to them (what lets a tile draw its share
  before the plane is done);
* tiles that simulate their inferred points of priority below the threshold
  (:func:`study.tiles.sample_threshold`) hold every point of the plane's final
  sample, whatever the tiles leave for the plane to refine (synthetic maps);
* a tiled study with ``AdaptivePlan.sample_in_tiles`` on a real LocalCluster
  computes no point list for its sample, and its ``simulated`` and
  ``verification`` arrays equal those of the study without tiles (and of the
  default, the sample as its own round).
"""

from __future__ import annotations

import io

import numpy as np
import pytest
import xarray as xr
from test_adaptive import N_B, N_R, map_with_features, synthetic, truth
from test_adaptive_tiles import ONE_PLANE

from study import Study
from study.tiles import _with_sample, sample_threshold
from tasks.adaptive import sample_priority, verification_sample
from tasks.stream import StreamRefinement
from tasks.tiles import refine_tile, strips


def test_priority_depends_on_index_and_seed_only_and_is_uniform():
    idx = np.arange(200_000)
    u = sample_priority(idx, 0)
    np.testing.assert_array_equal(sample_priority(idx[::-1], 0), u[::-1])  # per point
    np.testing.assert_array_equal(sample_priority(idx[5000:6000], 0), u[5000:6000])
    assert (u >= 0).all() and (u < 1).all()
    counts = np.histogram(u, bins=20, range=(0, 1))[0]  # 10,000 expected per bin
    assert np.abs(counts - 10_000).max() < 500  # 5 standard deviations
    other = sample_priority(idx, 1)
    assert abs(np.corrcoef(u, other)[0, 1]) < 0.02 and (u != other).mean() > 0.999


def test_sample_is_the_points_below_the_fraction_at_least_the_minimum():
    inferred = np.flatnonzero(np.arange(100_000) % 7 != 0)  # any set of flat indices
    u = sample_priority(inferred)
    sample = verification_sample(inferred, 0.005, 200)
    np.testing.assert_array_equal(sample, inferred[u < 0.005])
    assert abs(sample.size - 0.005 * inferred.size) < 5 * np.sqrt(0.005 * inferred.size)
    few = verification_sample(inferred[:10_000], 0.005, 200)  # ~50 below: the minimum
    assert few.size == 200
    np.testing.assert_array_equal(few, np.sort(inferred[:10_000][np.argsort(u[:10_000])[:200]]))
    assert verification_sample(inferred[:150], 0.005, 200).size == 150  # all of them
    # fewer inferred points (the plane refined further): the same sample restricted
    kept = inferred[inferred % 3 != 0]
    np.testing.assert_array_equal(
        verification_sample(kept, 0.005, 200), np.intersect1d(sample, kept)
    )


@pytest.mark.parametrize(("step", "minimum"), [(16, 200), (16, 20), (8, 600)])
def test_tiles_candidates_hold_the_planes_final_sample(step, minimum):
    batch = synthetic(map_with_features)
    lab = truth(map_with_features)
    fraction, n = 0.005, N_R * N_B
    threshold = sample_threshold(fraction, minimum, n)

    def simulate(r, beta, given):  # r and beta are the grid indices here; no orbits
        return batch(r.astype(int), beta.astype(int)) | {"final": np.full((r.size, 4), np.nan)}

    plane = StreamRefinement((N_R, N_B), step)
    plane.take()
    simulated, candidates = [], []
    for i0, i1 in strips(N_R, step, 4):
        axis_r, axis_b = np.arange(i0, i1 + 1, dtype=float), np.arange(N_B, dtype=float)
        idx, arrays, final = refine_tile(simulate, axis_r, axis_b, step)
        task = {"verify": (threshold, 0), "r": axis_r, "beta": axis_b}
        task |= {"offset": i0 * N_B, "coarse_step": step}
        idx, arrays, final = _with_sample(simulate, task, idx, arrays, final)
        i, j = np.unravel_index(idx, (i1 - i0 + 1, N_B))
        np.testing.assert_array_equal(arrays["regime"], lab[i0 + i, j])
        flat = idx + i0 * N_B
        simulated.append(flat[~arrays["verify"]])
        candidates.append(flat[arrays["verify"]])
    points = np.unique(np.concatenate(simulated))
    plane.accept(points, batch(*np.unravel_index(points, plane.shape)))
    while (idx := plane.take()).size:
        idx = idx[~plane.simulated.reshape(-1)[idx]]
        if idx.size:
            plane.accept(idx, batch(*np.unravel_index(idx, plane.shape)))
    sample = plane.verification(fraction, minimum, 0)
    cand = np.unique(np.concatenate(candidates))
    assert sample.size >= minimum and np.isin(sample, cand).all()
    assert not plane.simulated.reshape(-1)[cand[np.isin(cand, points)]].size  # disjoint
    assert cand.size <= 1.6 * sample.size + 10  # little simulated beyond the sample


@pytest.mark.cluster
def test_sample_inside_the_tiles_needs_no_list_and_gives_the_same_map(
    tmp_path, cluster_client, monkeypatch
):
    from study import run_study
    from study.adaptive import AdaptivePlan, PointList

    path = tmp_path / "one.toml"
    path.write_text(ONE_PLANE, encoding="utf-8")
    study = Study.from_toml(path)
    real_accept = AdaptivePlan.accept
    phases: list[str] = []

    def record(self, unit, arrays, work):
        if isinstance(unit, PointList):
            phases.append(unit.phase)
        real_accept(self, unit, arrays, work)

    monkeypatch.setattr(AdaptivePlan, "accept", record)
    out = {}
    for tiles, inside in ((True, True), (True, False), (False, True)):
        monkeypatch.setattr(AdaptivePlan, "tiles", tiles)
        monkeypatch.setattr(AdaptivePlan, "sample_in_tiles", inside)
        phases.clear()
        log = io.StringIO()
        out[tiles, inside] = tmp_path / f"tiles-{tiles}-{inside}.nc"
        run_study(study, out[tiles, inside], client=cluster_client, progress=False, stream=log)
        assert ("8 of 8 tiles computed" in log.getvalue()) is tiles
        assert ("verify" in phases) is not (tiles and inside)  # a sample round, or none
    with (
        xr.open_dataset(out[True, True]) as a,
        xr.open_dataset(out[True, False]) as b,
        xr.open_dataset(out[False, True]) as c,
    ):
        for name in ("simulated", "verification", "regime"):
            np.testing.assert_array_equal(a[name].values, b[name].values)
            np.testing.assert_array_equal(a[name].values, c[name].values)
        sampled = int((a["verification"].values > 0).sum())
        assert sampled == a.attrs["verification_sampled"] == c.attrs["verification_sampled"]
        assert sampled >= 200


def test_tiles_go_out_costliest_predicted_first():
    from study.tiles import longest_first

    rows = strips(N_R, 16, 4)  # 4 tiles of 4 coarse cells
    r = np.linspace(0.1, 3.0, N_R)
    assert longest_first(rows, None, r, 16) == rows  # no hint: the order of r
    hint = np.zeros((N_R, N_B), dtype=bool)
    assert longest_first(rows, hint, r, 16) == rows  # equal points: small r costs more
    hint[rows[2][0] + 3, :] = True  # a boundary across the third tile
    assert longest_first(rows, hint, r, 16)[0] == rows[2]
    assert sorted(longest_first(rows, hint, r, 16)) == rows
