"""Tiles of an adaptive plane refined inside the workers (study.tiles, tasks.tiles).

* tiles are strips of whole coarse cells covering the plane; their keys name
  their rows and nothing else passes for one;
* the refinement of each tile alone, its points then handed to the plane's
  refinement which continues where the tiles meet, ends at the same simulated
  points and labels as the plane's refinement alone (synthetic labellings,
  with and without a hint);
* a tiled study through the CLI (a real LocalCluster) gives the same labels and
  simulated points as the study without tiles, and its simulated points the
  labels of a dense ``tasks.classify``;
* a study interrupted after its first tile resumes reusing that tile (no tile
  task for it) and ends at the same map as a clean run.
"""

from __future__ import annotations

import io
import subprocess
import sys

import numpy as np
import pytest
import xarray as xr
from test_adaptive import ADAPTIVE, N_B, N_R, map_with_features, synthetic, truth
from test_study_cluster import RUN_TIMEOUT, _env

from study import Study
from study.errors import StudyInterrupted
from study.tiles import TILE_WORD, tile_key, tile_layout, tile_rows
from tasks import Scene, classify
from tasks.adaptive import coarse_nodes
from tasks.stream import StreamRefinement
from tasks.tiles import refine_tile, strips

#: One plane of 128 x 40 (16 coarse cells of 8 steps along r: 8 tiles on 2 threads).
ONE_PLANE = ADAPTIVE.replace("gamma = {values = [1.0, 2.0]}", "gamma = 1.0").replace(
    "num = 64", "num = 129"
)


# ------------------------------------------------------------------ layout and keys
@pytest.mark.parametrize(
    ("n_r", "step", "k"), [(1000, 16, 8), (129, 8, 3), (64, 8, 20), (17, 16, 4)]
)
def test_tiles_are_strips_of_whole_coarse_cells_covering_the_plane(n_r, step, k):
    tiles = strips(n_r, step, k)
    nodes = set(coarse_nodes(n_r, step).tolist())
    cells = len(nodes) - 1
    assert len(tiles) == min(k, cells)
    assert tiles[0][0] == 0 and tiles[-1][1] == n_r - 1
    for (_, a1), (b0, _) in zip(tiles, tiles[1:], strict=False):
        assert a1 == b0  # neighbours share their edge row
    for i0, i1 in tiles:
        assert i0 in nodes and i1 in nodes and i1 > i0
    widths = [sum(1 for n in nodes if i0 < n <= i1) for i0, i1 in tiles]
    assert max(widths) - min(widths) <= 1  # whole cells, balanced


def test_tile_layout_needs_two_tiles_of_two_cells():
    assert tile_layout(64, 8, 2) == strips(64, 8, 4)  # 8 cells: 4 tiles of 2
    assert len(tile_layout(1000, 16, 2)) == 8  # 4 per worker thread
    assert tile_layout(40, 16, 2) == []  # 3 cells: one tile would be the plane
    assert tile_layout(17, 16, 8) == []


def test_tile_keys_name_their_rows_and_nothing_else_passes():
    key = tile_key("sweep-pts-abc", (16, 32))
    assert tile_rows("sweep-pts-abc", key) == (16, 32)
    assert tile_rows("sweep-pts-abd", key) is None  # another plane
    assert tile_rows("sweep-pts-abc", key.replace("16to32", "16to48")) is None  # edited rows
    assert tile_rows("sweep-pts-abc", "sweep-pts-abc-12-0123456789abcdef") is None  # a list
    assert tile_rows("sweep-pts-abc", f"sweep-pts-abc-{TILE_WORD}x-00") is None


# ------------------------------------------------------------------ tiles, then the plane
def _refined(ref: StreamRefinement, batch) -> StreamRefinement:
    """Answer the refinement's requests (those not simulated yet) until it is done."""
    while not ref.done:
        idx = ref.take()
        idx = idx[~ref.simulated.reshape(-1)[idx]]
        if idx.size:
            ref.accept(idx, batch(*np.unravel_index(idx, ref.shape)))
    return ref


@pytest.mark.parametrize("hinted", [False, True])
def test_tiles_then_the_plane_end_at_the_plane_refinements_map(hinted):
    batch = synthetic(map_with_features)
    lab = truth(map_with_features)
    hint = None
    if hinted:  # the points beside a change of label along r
        hint = np.zeros(lab.shape, dtype=bool)
        hint[1:] |= lab[1:] != lab[:-1]
        hint[:-1] |= lab[1:] != lab[:-1]
    plain = _refined(StreamRefinement((N_R, N_B), 16, hint), batch)

    def simulate(r, beta, given):  # r and beta are the grid indices here; no orbits
        return batch(r.astype(int), beta.astype(int)) | {"final": np.full((r.size, 4), np.nan)}

    plane = StreamRefinement((N_R, N_B), 16, hint)
    plane.take()  # the coarse lattice: the tiles simulate it
    tiled = []
    for i0, i1 in strips(N_R, 16, 4):
        axis_r = np.arange(i0, i1 + 1, dtype=float)
        part = None if hint is None else hint[i0 : i1 + 1]
        idx, arrays, final = refine_tile(simulate, axis_r, np.arange(N_B, dtype=float), 16, part)
        assert np.isnan(final).all() and idx.size == np.unique(idx).size
        i, j = np.unravel_index(idx, (i1 - i0 + 1, N_B))
        np.testing.assert_array_equal(arrays["regime"], lab[i0 + i, j])  # its own points
        tiled.append(idx + i0 * N_B)  # the plane's flat indices
    points = np.unique(np.concatenate(tiled))  # an edge row is in two tiles
    plane.accept(points, batch(*np.unravel_index(points, plane.shape)))
    _refined(plane, batch)
    np.testing.assert_array_equal(plane.simulated, plain.simulated)
    np.testing.assert_array_equal(plane.result()["regime"], plain.result()["regime"])
    assert plane.simulated.sum() < 0.2 * plane.n_points


# ------------------------------------------------------------------ studies
def _open(path):
    """Labels and simulated points of a result, as ``(..., r, beta)`` arrays, and its axes."""
    with xr.open_dataset(path) as ds:
        ds = ds.transpose(..., "r", "beta")
        return ds["regime"].values, ds["simulated"].values, ds["r"].values, ds["beta"].values


@pytest.mark.cluster
def test_tiled_study_through_the_cli_equals_the_untiled_one(tmp_path, cluster_client, monkeypatch):
    from study import run_study
    from study.adaptive import AdaptivePlan

    (tmp_path / "tiled.toml").write_text(ADAPTIVE, encoding="utf-8")
    cli = subprocess.run(
        [sys.executable, "-m", "study", "run", "tiled.toml", "-o", "tiled.nc", "--workers", "2"],
        cwd=tmp_path,
        env=_env(),
        capture_output=True,
        text=True,
        timeout=RUN_TIMEOUT,
    )
    assert cli.returncode == 0, cli.stderr
    planes = [ln for ln in cli.stderr.splitlines() if "points simulated" in ln]
    assert len(planes) == 2 and all("4 of 4 tiles computed" in ln for ln in planes), cli.stderr

    monkeypatch.setattr(AdaptivePlan, "tiles", False)
    log = io.StringIO()
    study = Study.from_toml(tmp_path / "tiled.toml")
    run_study(study, tmp_path / "untiled.nc", client=cluster_client, progress=False, stream=log)
    assert "tiles" not in log.getvalue()

    regime, simulated, r, beta = _open(tmp_path / "tiled.nc")
    regime_u, simulated_u, _, _ = _open(tmp_path / "untiled.nc")
    np.testing.assert_array_equal(regime, regime_u)
    np.testing.assert_array_equal(simulated, simulated_u)
    # the simulated points hold the dense grid's labels (the plane gamma = 1)
    grid = np.meshgrid(r, beta, indexing="ij")
    dense = classify(Scene("ground", 2, 1, gamma=1.0, kappa=1.0), *grid, fidelity="fast").regime
    sim = simulated[0].astype(bool)
    assert sim.sum() > 0.05 * sim.size
    np.testing.assert_array_equal(regime[0][sim], dense[sim])


@pytest.mark.cluster
def test_an_interrupted_tiled_study_resumes_reusing_its_finished_tile(
    tmp_path, cluster_client, monkeypatch
):
    from study import run_study
    from study.adaptive import AdaptivePlan
    from study.tiles import Tile

    path = tmp_path / "one.toml"
    path.write_text(ONE_PLANE, encoding="utf-8")
    study = Study.from_toml(path)
    real_accept = AdaptivePlan.accept
    tiles: list[tuple[str, int]] = []  # (key, points) of the tiles accepted

    def first_tile_then_ctrl_c(self, unit, arrays, work):
        real_accept(self, unit, arrays, work)
        if isinstance(unit, Tile):
            tiles.append((unit.key, int(arrays["index"].size)))
            raise KeyboardInterrupt

    monkeypatch.setattr(AdaptivePlan, "accept", first_tile_then_ctrl_c)
    out = tmp_path / "one.nc"
    with pytest.raises(StudyInterrupted):
        run_study(study, out, client=cluster_client, progress=False, stream=io.StringIO())
    work = tmp_path / "one.nc.work"
    saved = sorted(p.stem for p in work.glob(f"*/*-{TILE_WORD}*.npz"))
    assert saved == [tiles[0][0]] and not out.exists()

    def record(self, unit, arrays, work):  # the rerun: which tiles does it compute?
        if isinstance(unit, Tile):
            tiles.append((unit.key, int(arrays["index"].size)))
        real_accept(self, unit, arrays, work)

    monkeypatch.setattr(AdaptivePlan, "accept", record)
    log = io.StringIO()
    run_study(study, out, client=cluster_client, progress=False, stream=log)
    computed = [key for key, _ in tiles[1:]]
    assert len(computed) == 7 and saved[0] not in computed  # 8 tiles, one reused
    line = next(ln for ln in log.getvalue().splitlines() if "points simulated" in ln)
    reused = int(line.split(" saved points reused")[0].split()[-1].replace(",", ""))
    assert reused == tiles[0][1] > 0 and "7 of 8 tiles computed" in line

    monkeypatch.setattr(AdaptivePlan, "accept", real_accept)
    clean = tmp_path / "clean.nc"
    run_study(study, clean, client=cluster_client, progress=False, stream=io.StringIO())
    regime, simulated, _, _ = _open(out)
    regime_c, simulated_c, _, _ = _open(clean)
    np.testing.assert_array_equal(regime, regime_c)
    np.testing.assert_array_equal(simulated, simulated_c)
