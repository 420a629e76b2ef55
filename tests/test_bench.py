"""``study bench`` (study.bench.main_bench, quick set): the files and their table."""

from __future__ import annotations

import numpy as np
import pytest

from study.bench import SCENES, bench_markdown, bench_points, main_bench
from tasks import PRESETS


def test_bench_points_are_fixed_and_near_boundaries():
    from analysis.closed_form import boundaries

    scene = SCENES["2dof_ground_m2"]
    a = bench_points(scene, 6, 2, seed=7)
    b = bench_points(scene, 6, 2, seed=7)
    np.testing.assert_array_equal(a.r, b.r)
    np.testing.assert_array_equal(a.beta, b.beta)
    assert a.r.size == 6 and np.all((a.r >= 0.1) & (a.r <= 3.0)) and np.all(a.beta >= 0)
    near = a.near > 0
    bc, bm = boundaries(scene, a.r[near], method="exact")
    bound = np.where(a.near[near] == 1, bc, bm)
    rel = a.side[near] * (a.beta[near] / bound - 1.0)
    assert np.all((rel >= 0.02 - 1e-12) & (rel <= 0.15 + 1e-12))
    assert a.bisect_r.size == 2 and np.all(a.b_cont < a.b_motion)


@pytest.mark.slow
def test_quick_bench_writes_table_and_figure(tmp_path):
    md = main_bench(tmp_path / "out", quick=True)
    assert md == tmp_path / "out" / "bench.md"
    png = tmp_path / "out" / "pareto.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 5000
    text = md.read_text()
    assert "| platform |" in text and "| numpy / scipy / numba |" in text
    rows = [line for line in text.splitlines() if line.startswith("| ")]
    for preset in PRESETS:
        assert sum(line.startswith(f"| classify `{preset}` |") for line in rows) == 1
    assert sum(line.startswith("| baseline (paper") for line in rows) == 1
    # the reference preset agrees with itself; every scene has a row
    assert "| classify `exact` |" in text
    exact_row = next(line for line in rows if line.startswith("| classify `exact` |"))
    assert "0.0 % (0/" in exact_row
    for label in SCENES:
        assert f"| `{label}` |" in text
    assert bench_markdown.__doc__
