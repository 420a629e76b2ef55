"""An adaptive study with the verification sample inside its tiles
(``AdaptivePlan.sample_in_tiles``), interrupted after its first tile, resumes
reusing that tile (no tile task for it, no point list for its sample) and ends
at the same labels, simulated points and verification sample as an
uninterrupted run (study.adaptive, study.tiles; a real LocalCluster).
"""

from __future__ import annotations

import io

import numpy as np
import pytest
import xarray as xr
from test_adaptive_tiles import ONE_PLANE

from study import Study
from study.errors import StudyInterrupted


@pytest.mark.cluster
def test_an_interrupted_run_with_the_sample_in_its_tiles_resumes_to_the_same_map(
    tmp_path, cluster_client, monkeypatch
):
    from study import run_study
    from study.adaptive import AdaptivePlan, PointList
    from study.tiles import TILE_WORD, Tile

    monkeypatch.setattr(AdaptivePlan, "tiles", True)
    monkeypatch.setattr(AdaptivePlan, "sample_in_tiles", True)
    path = tmp_path / "one.toml"
    path.write_text(ONE_PLANE, encoding="utf-8")
    study = Study.from_toml(path)
    real_accept = AdaptivePlan.accept
    tiles: list[tuple[str, int, int]] = []  # (key, points, sampled) of the tiles accepted
    phases: list[str] = []  # of the point lists accepted

    def record(self, unit, arrays, work):
        if isinstance(unit, Tile):
            verify = int(np.count_nonzero(arrays["verify"])) if "verify" in arrays else -1
            tiles.append((unit.key, int(arrays["index"].size), verify))
        elif isinstance(unit, PointList):
            phases.append(unit.phase)
        real_accept(self, unit, arrays, work)

    def first_tile_then_ctrl_c(self, unit, arrays, work):
        record(self, unit, arrays, work)
        if isinstance(unit, Tile):
            raise KeyboardInterrupt

    monkeypatch.setattr(AdaptivePlan, "accept", first_tile_then_ctrl_c)
    out = tmp_path / "one.nc"
    with pytest.raises(StudyInterrupted):
        run_study(study, out, client=cluster_client, progress=False, stream=io.StringIO())
    work = tmp_path / "one.nc.work"
    saved = sorted(p.stem for p in work.glob(f"*/*-{TILE_WORD}*.npz"))
    assert len(tiles) == 1 and saved == [tiles[0][0]] and not out.exists()
    assert tiles[0][2] > 0  # the tile drew its share of the sample

    monkeypatch.setattr(AdaptivePlan, "accept", record)
    log = io.StringIO()
    run_study(study, out, client=cluster_client, progress=False, stream=log)
    computed = [key for key, _, _ in tiles[1:]]
    assert len(computed) == 7 and saved[0] not in computed  # 8 tiles, the first reused
    assert "verify" not in phases  # the sample came from the tiles, the reused one too
    line = next(ln for ln in log.getvalue().splitlines() if "points simulated" in ln)
    reused = int(line.split(" saved points reused")[0].split()[-1].replace(",", ""))
    assert reused == tiles[0][1] and "7 of 8 tiles computed" in line

    monkeypatch.setattr(AdaptivePlan, "accept", real_accept)
    clean = tmp_path / "clean.nc"
    run_study(study, clean, client=cluster_client, progress=False, stream=io.StringIO())
    with xr.open_dataset(out) as a, xr.open_dataset(clean) as b:
        for name in ("regime", "simulated", "verification"):
            np.testing.assert_array_equal(a[name].values, b[name].values, err_msg=name)
        assert a.attrs["verification_sampled"] == b.attrs["verification_sampled"] >= 200
