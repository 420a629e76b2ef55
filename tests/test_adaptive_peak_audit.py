"""The random audit's adaptive map with a one-column peak of the exact motion bound
(docs/benchmarks.md, Random audit, seed 18): a 2DOF base chain with dashpots, contact
on the first DOF, 25 x 17 points, ``coarse_step = 4``, hint exact. At r = 4.396 (1.2 %
below a held resonance: motion bound 67.1 there, 25.4 and 23.8 at its neighbours) the
stick-slip points of that column lie inside cells of 4 steps whose corners are all no
motion; the hint alone (cells split down to ``HINT_CELL`` = 4 steps) left seven of them
inferred no motion in process, two outside the verification sample through ``study
run``. With the closed-form prediction keeping such cells open (tasks.adaptive.Refinement)
every label equals ``tasks.classify``, the independent truth (the simulation of every
point), both ways. Only the public paths are used, so the old code runs these too.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from analysis import predict
from analysis.adaptive import adaptive_map
from tasks import Scene, classify, regimes
from tasks.adaptive import coarse_nodes

AUDIT_M = [[0.409519, 0.0], [0.0, 0.162999]]
AUDIT_K = [[3.662481, -3.227477], [-3.227477, 3.227477]]
AUDIT_C = [[0.008974, 0.0], [0.0, 0.032267]]
AUDIT_STUDY = f"""
[study]
name = "audit_maps"
fidelity = "balanced"

[[scene]]
name = "adaptive"
contact = {{ground = 0}}
damping = {{matrix = {AUDIT_C}}}
matrices = {{mass = {AUDIT_M}, stiffness = {AUDIT_K}, load = {{base = [1.0, 1.0]}}}}
mode = "adaptive"
coarse_step = 4
verify_fraction = 0.0
hint = "exact"
r = {{start = 0.260045, stop = 6.878044, num = 25}}
beta = {{start = 0.0, stop = 94.85256, num = 17}}
"""


def _audit_scene() -> Scene:
    load = ("base", np.ones(2))
    return Scene.from_matrices(AUDIT_M, AUDIT_K, load, ("ground", 0), damping=np.array(AUDIT_C))


def _audit_axes() -> tuple[np.ndarray, np.ndarray]:
    return np.linspace(0.260045, 6.878044, 25), np.linspace(0.0, 94.85256, 17)


def test_the_audit_peak_of_the_motion_bound_is_found_in_process():
    scene = _audit_scene()
    r, beta = _audit_axes()
    res = adaptive_map(scene, r, beta, coarse_step=4, hint="exact", verify_fraction=0, verify_min=0)
    dense = classify(scene, *np.meshgrid(r, beta, indexing="ij")).regime
    column = np.flatnonzero(np.isclose(r, 4.3963, atol=1e-3))  # 1.2 % below the resonance
    assert column.size == 1 and (dense[column[0]] == regimes.STICK_SLIP).sum() >= 7
    np.testing.assert_array_equal(res.fields["regime"], dense)
    assert res.simulated_points < 0.3 * dense.size
    grid = np.meshgrid(r, beta, indexing="ij")
    assert (predict(scene, *grid, method="exact") == dense).all()  # exact closed forms here


def test_the_audit_peak_of_the_motion_bound_is_found_by_study_run(run_cli, tmp_path):
    (tmp_path / "maps.toml").write_text(AUDIT_STUDY, encoding="utf-8")
    proc = run_cli("run", "maps.toml", "-o", "maps.nc", timeout=300)
    assert proc.returncode == 0, proc.stderr
    with xr.open_dataset(tmp_path / "maps.nc") as ds:
        ds = ds.transpose("r", "beta", ...).load()
    r, beta = ds.r.values, ds.beta.values
    for axis, want in zip((r, beta), _audit_axes(), strict=True):
        np.testing.assert_allclose(axis, want, rtol=0, atol=1e-12)
    dense = classify(_audit_scene(), *np.meshgrid(r, beta, indexing="ij")).regime
    np.testing.assert_array_equal(ds.regime.values, dense)  # simulated and inferred alike
    # (the verification sample, at least 200 points, simulates most of the inferred ones;
    # the hint alone left two stick-slip points of the peak inferred no motion outside it)
    refined = ds.simulated.values & (ds.verification.values == 0)
    assert coarse_nodes(25, 4).size == 7 and refined.mean() < 0.3
