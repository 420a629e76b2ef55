"""Adaptive maps (tasks.adaptive, analysis.adaptive, study mode = "adaptive").

* synthetic labellings with known regions (a disc, a thin strip, islands larger
  and smaller than the coarse spacing, an undetermined patch): the refined map
  equals the true labels where the module's guarantee says it must, every pair
  of differently labelled neighbours is simulated (boundaries resolved to one
  grid step), and the verification sample measures the true error;
* a small real scene against a dense ``tasks.classify``;
* refinement without barriers (``StreamRefinement``) fed point lists in shuffled
  orders, several in flight: the same simulated points and the same fields as the
  wave refinement, on synthetic panels and a real scene;
* a study with ``mode = "adaptive"`` on a real LocalCluster (processes,
  127.0.0.1), interrupted after a few point lists and resumed, opened with xarray
  and compared with the in-process refinement and with ``tasks.classify``.
"""

from __future__ import annotations

import io

import numpy as np
import pytest
import xarray as xr

from analysis.adaptive import adaptive_map, closed_form_hint, curve_hint
from study import Study
from study.errors import StudyError, StudyInterrupted
from tasks import Scene, classify, regimes
from tasks.adaptive import Refinement, coarse_nodes, refine
from tasks.result import FIELDS
from tasks.stream import StreamRefinement

N_R, N_B = 256, 128


def synthetic(label_fn):
    """A batch classifier from a labelling function of (i_r, i_beta) -> regime code."""

    def batch(i, j):
        out = {k: np.zeros(i.size, dtype=dt) for k, (dt, _) in FIELDS.items()}
        out["regime"] = label_fn(i, j).astype(np.int8)
        out["converged"] = out["regime"] >= 0
        out["slip_amplitude"] = i + 1000.0 * j  # identifies the point a value came from
        return out

    return batch


def truth(label_fn, shape=(N_R, N_B)):
    i, j = np.meshgrid(np.arange(shape[0]), np.arange(shape[1]), indexing="ij")
    return label_fn(i, j).astype(np.int8)


def map_with_features(i, j):
    """Continuous below a wavy curve, no motion above a sloped line, a disc and a thin strip."""
    x, y = i / N_R, j / N_B
    lab = np.where(y < 0.3 + 0.15 * np.sin(5 * x), regimes.CONTINUOUS, regimes.STICK_SLIP)
    lab = np.where(y > 0.85 - 0.1 * x, regimes.NO_MOTION, lab)
    lab = np.where((i - 60) ** 2 + (j - 80) ** 2 < 15**2, regimes.NO_MOTION, lab)  # disc
    return np.where((i >= 150) & (i <= 152) & (j > 30), regimes.NO_MOTION, lab)  # strip, 3 wide


def assert_boundaries_simulated(simulated, labels):
    """Every pair of horizontal or vertical neighbours with different labels is resolved
    to one step by simulation: both points are simulated, or the pair is the middle
    of a resolved strip (tasks.adaptive.Refinement._resolved_strip): the pairs one
    step before and after it along the boundary are simulated, with the same two
    labels."""
    for axis in (0, 1):
        a = [slice(None), slice(None)]
        b = [slice(None), slice(None)]
        a[axis], b[axis] = slice(None, -1), slice(1, None)
        la, lb = labels[tuple(a)], labels[tuple(b)]
        sa, sb = simulated[tuple(a)], simulated[tuple(b)]
        differ = la != lb
        both = sa & sb
        # the strip's middle pair: the pairs on both sides along the other axis
        other = 1 - axis
        n = la.shape[other]
        middle = np.zeros_like(differ)
        lo = [slice(None), slice(None)]
        mid = [slice(None), slice(None)]
        hi = [slice(None), slice(None)]
        lo[other], mid[other], hi[other] = slice(0, n - 2), slice(1, n - 1), slice(2, n)
        lo, mid, hi = tuple(lo), tuple(mid), tuple(hi)
        middle[mid] = (
            both[lo]
            & both[hi]
            & (la[lo] == la[mid])
            & (la[hi] == la[mid])
            & (lb[lo] == lb[mid])
            & (lb[hi] == lb[mid])
        )
        assert (both | middle)[differ].all()
        assert both[differ].mean() > 0.5  # strips save at most every second pair


def test_map_with_disc_and_strip_equals_truth_and_is_cheap():
    expected = truth(map_with_features)
    res = refine((N_R, N_B), synthetic(map_with_features), coarse_step=16)
    np.testing.assert_array_equal(res.fields["regime"], expected)
    assert_boundaries_simulated(res.fields["simulated"], expected)
    assert res.fields["converged"].all()
    assert res.simulated_fraction < 0.2  # 256 x 128 with ~1000 boundary points
    v = res.verification
    assert v.sampled == 200 and v.agree == 200
    # inferred points copy the nearest simulated corner: the value names a simulated point
    src = res.fields["slip_amplitude"][~res.fields["simulated"]]
    si, sj = (src % 1000).astype(int), (src // 1000).astype(int)
    assert res.fields["simulated"][si, sj].all()
    assert (expected[si, sj] == res.fields["regime"][~res.fields["simulated"]]).all()


@pytest.mark.parametrize("step", [4, 8, 16])
def test_islands_of_the_coarse_spacing_are_always_found(step):
    """The guarantee: a region containing a step x step square is found, wherever it lies."""
    rng = np.random.default_rng(step)
    for _ in range(12):
        i0, j0 = rng.integers(1, N_R - step - 2), rng.integers(1, N_B - step - 2)

        def island(i, j, i0=i0, j0=j0):
            inside = (i >= i0) & (i <= i0 + step) & (j >= j0) & (j <= j0 + step)
            return np.where(inside, regimes.NO_MOTION, regimes.CONTINUOUS)

        res = refine(
            (N_R, N_B), synthetic(island), coarse_step=step, verify_min=0, verify_fraction=0
        )
        np.testing.assert_array_equal(res.fields["regime"], truth(island))


def test_island_smaller_than_the_spacing_needs_a_hint():
    """Narrower than the coarse spacing and between nodes: missed, as documented; a hint over
    it (as the closed forms give) makes refinement find it and resolve it exactly."""
    nodes = coarse_nodes(N_R, 16)
    i0 = int(nodes[3]) + 5  # between coarse nodes along r and beta

    def island(i, j):
        inside = (i >= i0) & (i <= i0 + 4) & (j >= 37) & (j <= 41)
        return np.where(inside, regimes.NO_MOTION, regimes.CONTINUOUS)

    plain = refine((N_R, N_B), synthetic(island), coarse_step=16, verify_min=0, verify_fraction=0)
    assert (plain.fields["regime"] == regimes.CONTINUOUS).all()  # missed: no simulated point on it
    hint = np.zeros((N_R, N_B), dtype=bool)
    hint[i0 + 2, 39] = True
    hinted = refine((N_R, N_B), synthetic(island), 16, hint, verify_min=0, verify_fraction=0)
    np.testing.assert_array_equal(hinted.fields["regime"], truth(island))


def test_undetermined_points_are_refined_and_never_given_a_regime():
    def lab(i, j):
        out = np.where(j < 64, regimes.CONTINUOUS, regimes.STICK_SLIP)
        return np.where((i > 100) & (i < 140) & (j > 90), regimes.NOT_CONVERGED, out)

    res = refine((N_R, N_B), synthetic(lab), coarse_step=16)
    np.testing.assert_array_equal(res.fields["regime"], truth(lab))
    assert_boundaries_simulated(res.fields["simulated"], truth(lab))
    np.testing.assert_array_equal(res.fields["converged"], truth(lab) >= 0)


def test_verification_sample_measures_the_true_error():
    """With every inferred point in the sample, the measured agreement is the true one."""
    nodes = coarse_nodes(N_R, 16)
    i0 = int(nodes[5]) + 4

    def lab(i, j):  # a small island the refinement misses (see above)
        inside = (i >= i0) & (i <= i0 + 3) & (j >= 20) & (j <= 23)
        return np.where(inside, regimes.STICK_SLIP, regimes.CONTINUOUS)

    ref = Refinement((N_R, N_B), 16)
    batch = synthetic(lab)
    while (idx := ref.wave()).size:
        ref.accept(idx, batch(*np.unravel_index(idx, ref.shape)))
    inferred = ref.result()["regime"].copy()
    wrong_before = int((inferred != truth(lab)).sum())
    assert wrong_before == 16
    sample = ref.verification(fraction=1.0)
    summary = ref.accept_verification(sample, batch(*np.unravel_index(sample, ref.shape)))
    assert summary.sampled == summary.inferred == sample.size
    assert summary.sampled - summary.agree == wrong_before
    out = ref.result()
    np.testing.assert_array_equal(out["regime"], truth(lab))  # the sample's values are kept
    assert out["simulated"].all()
    assert (out["verification"] == 2).sum() == wrong_before


def test_line_maps_and_bad_settings():
    res = refine((1, 50), synthetic(lambda i, j: np.where(j < 20, 2, 1)), coarse_step=8)
    np.testing.assert_array_equal(res.fields["regime"][0], np.where(np.arange(50) < 20, 2, 1))
    with pytest.raises(ValueError, match="coarse_step"):
        Refinement((10, 10), 0)
    with pytest.raises(ValueError, match="hint"):
        Refinement((10, 10), 4, np.zeros((3, 3), dtype=bool))


def test_curve_hint_marks_both_sides_and_steep_parts():
    beta = np.linspace(0.0, 1.0, 11)
    hint = curve_hint(beta, np.array([0.25, 0.25, 0.85, np.inf]))
    assert hint[0].nonzero()[0].tolist() == [2, 3]
    assert hint[1].nonzero()[0].tolist() == [2, 3, 4, 5, 6, 7, 8, 9]  # the jump to 0.85
    assert hint[2].nonzero()[0].tolist() == [8, 9] and not hint[3].any()


def test_real_scene_agrees_with_dense_classify():
    """SDOF ground (Fig. 3): Den Hartog's curve and the motion bound beta = 1."""
    scene = Scene("ground", 1)
    r = np.linspace(0.05, 3.0, 96)
    beta = np.linspace(0.0, 1.2, 48)
    res = adaptive_map(scene, r, beta, coarse_step=8, fidelity="fast")
    dense = classify(scene, *np.meshgrid(r, beta, indexing="ij"), fidelity="fast").regime
    sim = res.fields["simulated"]
    np.testing.assert_array_equal(res.fields["regime"][sim], dense[sim])  # same simulations
    assert (res.fields["regime"] == dense).mean() >= 0.998
    assert sim.mean() < 0.5
    assert_boundaries_simulated(sim, res.fields["regime"])
    assert closed_form_hint(scene, r, beta).any()


# --------------------------------------------------------------------------- study files
ADAPTIVE = """
[study]
name = "adaptive"
fidelity = "fast"
chunk_points = 60

[[scene]]
name = "sweep"
contact = "ground"
dof = 2
mode = "adaptive"
coarse_step = 8
verify_fraction = 0.01
gamma = {values = [1.0, 2.0]}
r = {start = 0.1, stop = 2.4, num = 64}
beta = {start = 0.0, stop = 1.5, num = 40}
"""


@pytest.mark.parametrize(
    ("edit", "field"),
    [
        ("coarse_step = 8", "coarse_step = 0"),
        ('mode = "adaptive"', 'mode = "grid"'),
        ("verify_fraction = 0.01", "verify_fraction = 1.5"),
        ("coarse_step = 8", 'hint = "closest"'),
    ],
)
def test_adaptive_scene_validation(study_file, edit, field):
    with pytest.raises(StudyError) as err:
        Study.from_toml(study_file(ADAPTIVE.replace(edit, field)))
    key = field.split(" =")[0] if "mode" not in field else "coarse_step"
    assert f"scene[0].{key}" in str(err.value)
    pts = ADAPTIVE.replace("r = {start = 0.1, stop = 2.4, num = 64}\n", "").replace(
        "beta = {start = 0.0, stop = 1.5, num = 40}\n", "points = [[1.0, 0.1]]\n"
    )
    with pytest.raises(StudyError, match="needs r and beta axes"):
        Study.from_toml(study_file(pts))


@pytest.mark.cluster
def test_adaptive_study_on_local_cluster_resumes_after_interruption(
    tmp_path, monkeypatch, cluster_client
):
    """On the session's LocalCluster (conftest.cluster_client: 2 worker processes on
    127.0.0.1): the interruption is raised in this process, no worker is stopped."""
    from study import run_study
    from study.adaptive import AdaptivePlan

    study = Study.from_toml(_write(tmp_path / "adaptive.toml", ADAPTIVE))
    out = tmp_path / "adaptive.nc"
    client = cluster_client
    real_accept = AdaptivePlan.accept
    kept = []  # points of the first plane's point lists saved before the interruption

    def interrupted_accept(self, unit, arrays, *args, **kwargs):
        real_accept(self, unit, arrays, *args, **kwargs)
        if unit.sweep == (0,):  # a tile (study.tiles) saves the points it simulated
            kept.append(arrays["index"].size if "index" in arrays else unit.n_points)
            if len(kept) == 4:  # Ctrl-C after the fourth point list of the first plane
                raise KeyboardInterrupt

    monkeypatch.setattr(AdaptivePlan, "accept", interrupted_accept)
    with pytest.raises(StudyInterrupted):
        run_study(study, out, client=client, progress=False, stream=io.StringIO())
    assert not out.exists() and (tmp_path / "adaptive.nc.work").is_dir()
    monkeypatch.setattr(AdaptivePlan, "accept", real_accept)
    log = io.StringIO()
    run_study(study, out, client=client, progress=False, stream=log)
    assert not (tmp_path / "adaptive.nc.work").exists()
    first = [
        line for line in log.getvalue().splitlines() if "sweep[0]:" in line and "reused" in line
    ]
    assert len(first) == 1 and "verification: 200 of" in first[0]
    reused = int(first[0].split(" saved points reused")[0].split()[-1].replace(",", ""))
    assert reused >= sum(kept) > 0  # the points of those lists came from the work folder

    tree = xr.open_dataset(out)
    assert tree["regime"].dims == ("gamma", "beta", "r")
    assert tree["simulated"].dtype == bool and tree["verification"].dims == ("gamma", "beta", "r")
    assert tree.attrs["mode"] == "adaptive" and tree.attrs["adaptive_coarse_step"] == 8
    assert tree.attrs["verification_sampled"] == 2 * 200
    r, beta = tree["r"].values, tree["beta"].values
    for k, g in enumerate((1.0, 2.0)):
        scene = Scene("ground", 2, 1, gamma=g, kappa=1.0)
        local = adaptive_map(scene, r, beta, coarse_step=8, verify_fraction=0.01, fidelity="fast")
        ds = tree.isel(gamma=k).transpose(..., "r", "beta")  # the arrays of adaptive_map
        np.testing.assert_array_equal(ds["simulated"].values, local.fields["simulated"])
        np.testing.assert_array_equal(ds["regime"].values, local.fields["regime"])
        np.testing.assert_array_equal(ds["verification"].values, local.fields["verification"])
        sim = ds["simulated"].values
        dense = classify(scene, *np.meshgrid(r, beta, indexing="ij"), fidelity="fast")
        np.testing.assert_array_equal(ds["regime"].values[sim], dense.regime[sim])
        # (cycles depend on the warm starts' seeds; the other fields agree to the
        # polish, here bounded by the fast preset's event times to 1e-9: docs/api.md)
        for name in ("stops_per_cycle", "period", "asymptotic", "converged"):
            np.testing.assert_array_equal(ds[name].values[sim], getattr(dense, name)[sim])
        np.testing.assert_allclose(
            ds["stick_fraction"].values[sim], dense.stick_fraction[sim], rtol=0, atol=1e-7
        )
        assert (ds["regime"].values == dense.regime).mean() >= 0.99
    tree.close()


def _write(path, text):
    path.write_text(text, encoding="utf-8")
    return path


@pytest.mark.parametrize("axis", [0, 1])
def test_straight_boundary_costs_about_two_points_per_row(axis):
    """A boundary crossing every row (along r) or every column (along beta) between
    two grid lines: halving only across the boundary (Refinement._split_axes) and
    the resolved 1 x 2 strips simulate about 1.2 points per row beyond the coarse
    lattice (the two sides of every second row, and the halvings on the way);
    a split into four at every level, without strips, costs 3.3 times as much
    (481 and 961 points here)."""

    def step(i, j):
        k = i if axis == 0 else j
        cut = 101 if axis == 0 else 45  # between coarse nodes (every 16 steps)
        return np.where(k < cut, regimes.CONTINUOUS, regimes.STICK_SLIP)

    res = refine((N_R, N_B), synthetic(step), coarse_step=16, verify_min=0, verify_fraction=0)
    np.testing.assert_array_equal(res.fields["regime"], truth(step))
    rows = N_B if axis == 0 else N_R  # grid lines the boundary crosses
    coarse = coarse_nodes(N_R, 16).size * coarse_nodes(N_B, 16).size
    refined = res.simulated_points - coarse
    assert refined <= 1.25 * rows, (refined, rows)


@pytest.mark.parametrize("slope", [0.4, 1.0, 2.5])
def test_slanted_boundary_is_exact_and_cheap(slope):
    """A straight boundary crossing rows and columns (``slope`` rows per column): the map
    equals the truth, every differing pair is resolved, and beyond the coarse lattice the
    refinement costs at most 2.9 simulations per differing pair of neighbours (2.65-2.79
    here): a cell whose corners disagree along both axes is halved along one
    (Refinement._split_axes), and a 1 x 2 strip asks for the middles of its
    disagreeing long edges, then only for a uniform edge's middle the boundary passes
    next to (Refinement._strip_middles), instead of being split in two. Splitting
    the strips costs 2.94-3.29, halving both axes of a cell as well 3.27-3.76."""

    def lab(i, j):
        return np.where(j < slope * (i - 40) + 3, regimes.CONTINUOUS, regimes.STICK_SLIP)

    res = refine((N_R, N_B), synthetic(lab), coarse_step=16, verify_min=0, verify_fraction=0)
    expected = truth(lab)
    np.testing.assert_array_equal(res.fields["regime"], expected)
    assert_boundaries_simulated(res.fields["simulated"], expected)
    pairs = (expected[1:] != expected[:-1]).sum() + (expected[:, 1:] != expected[:, :-1]).sum()
    coarse = coarse_nodes(N_R, 16).size * coarse_nodes(N_B, 16).size
    assert res.simulated_points - coarse <= 2.9 * pairs, (res.simulated_points - coarse, pairs)


# --------------------------------------------------------------------------- no barriers
def shuffled_stream(shape, batch, seed, coarse_step=16, hint=None, dof=1, predicted=None):
    """A StreamRefinement driven as a cluster would: random batch sizes, up to four point
    lists in flight, results arriving in a random order."""
    rng = np.random.default_rng(seed)
    ref = StreamRefinement(shape, coarse_step, hint, dof=dof, predicted=predicted)
    inflight: list[np.ndarray] = []
    while not ref.done or inflight:
        while ref.ready and len(inflight) < 4:
            inflight.append(ref.take(int(rng.integers(1, 40))))
        idx = inflight.pop(int(rng.integers(len(inflight))))
        rng.shuffle(idx)
        ref.accept(idx, batch(*np.unravel_index(idx, shape)))
    return ref


def waves(shape, batch, coarse_step=16, hint=None, dof=1, predicted=None):
    ref = Refinement(shape, coarse_step, hint, dof=dof, predicted=predicted)
    while (idx := ref.wave()).size:
        ref.accept(idx, batch(*np.unravel_index(idx, shape)))
    return ref


def _disc_and_sine(i, j):
    lab = np.where(j < 40 + 30 * np.sin(i / 17.0), regimes.CONTINUOUS, regimes.STICK_SLIP)
    lab = np.where((i - 180) ** 2 + (j - 90) ** 2 < 11**2, regimes.NO_MOTION, lab)
    return np.where((i > 20) & (i < 40) & (j > 100) & (j < 110), regimes.NOT_CONVERGED, lab)


def _checker(i, j):  # many small features: cells reopened by their neighbours
    return np.where(((i // 13) + (j // 7)) % 3 == 0, regimes.NO_MOTION, regimes.CONTINUOUS)


def _slanted_three(i, j):  # slanted boundaries meeting: strips asking for second middles
    lab = np.where(j < 2.5 * (i - 40) + 3, regimes.CONTINUOUS, regimes.STICK_SLIP)
    return np.where(j > 0.45 * i + 50, regimes.NO_MOTION, lab)


@pytest.mark.parametrize("label_fn", [map_with_features, _disc_and_sine, _checker, _slanted_three])
@pytest.mark.parametrize("coarse_step", [8, 16])
def test_no_barriers_equals_waves_in_any_order(label_fn, coarse_step):
    batch = synthetic(label_fn)
    hint = np.zeros((N_R, N_B), dtype=bool)
    hint[:, 61] = True  # a hinted line that crosses no boundary of its own
    for h in (None, hint):
        ref_w = waves((N_R, N_B), batch, coarse_step, h)
        want = ref_w.result()
        assert len(ref_w.levels) > 3
        levels = shuffled_stream((N_R, N_B), batch, 99, coarse_step, h).level_sizes()
        assert sum(levels) == want["simulated"].sum() and len(levels) > 3
        for seed in range(3):
            ref_s = shuffled_stream((N_R, N_B), batch, seed, coarse_step, h)
            assert ref_s.level_sizes() == levels  # stored per plane: independent of order
            got = ref_s.result()
            np.testing.assert_array_equal(got["simulated"], want["simulated"])
            for name in ("regime", "converged", "slip_amplitude"):
                np.testing.assert_array_equal(got[name], want[name], err_msg=name)
    assert_boundaries_simulated(got["simulated"], got["regime"])


def test_no_barriers_equals_waves_on_a_real_scene():
    """2DOF ground contact (Fig. 4 style), real classify: same simulated points, same fields."""
    scene = Scene("ground", 2)
    r = np.linspace(0.05, 2.5, 80)
    beta = np.linspace(0.0, 1.5, 40)
    hint = closed_form_hint(scene, r, beta)
    cache: dict[int, dict] = {}  # one classify per point: both runs see the same values

    def batch(i, j):
        flat = np.ravel_multi_index((i, j), (r.size, beta.size))
        todo = np.array([f for f in flat if f not in cache], dtype=np.int64)
        if todo.size:
            ti, tj = np.unravel_index(todo, (r.size, beta.size))
            res = classify(scene, r[ti], beta[tj], fidelity="fast", design=True)
            for n, f in enumerate(todo):
                cache[int(f)] = {k: np.asarray(getattr(res, k))[n] for k in FIELDS}
        return {k: np.array([cache[int(f)][k] for f in flat]) for k in FIELDS}

    want = waves((r.size, beta.size), batch, 8, hint, dof=2).result()
    for seed in range(2):
        got = shuffled_stream((r.size, beta.size), batch, seed, 8, hint, dof=2).result()
        np.testing.assert_array_equal(got["simulated"], want["simulated"])
        for name in FIELDS:
            np.testing.assert_array_equal(got[name], want[name], err_msg=name)
    assert len(set(want["regime"].ravel().tolist())) >= 2
    assert want["simulated"].mean() < 0.6


def test_hint_set_after_the_coarse_lattice_changes_nothing():
    """The study computes the hint while the coarse lattice computes
    (StreamRefinement.set_hint before the first result): the same map as a hint
    given at construction; after the first result it is refused."""
    batch = synthetic(map_with_features)
    hint = np.zeros((N_R, N_B), dtype=bool)
    hint[:, 61] = True
    want = shuffled_stream((N_R, N_B), batch, 0, 16, hint).result()
    ref = StreamRefinement((N_R, N_B), 16)
    first = ref.take()
    ref.set_hint(hint)
    ref.accept(first, batch(*np.unravel_index(first, ref.shape)))
    while (idx := ref.take(50)).size:
        ref.accept(idx, batch(*np.unravel_index(idx, ref.shape)))
    got = ref.result()
    np.testing.assert_array_equal(got["simulated"], want["simulated"])
    np.testing.assert_array_equal(got["regime"], want["regime"])
    assert got["simulated"].sum() > shuffled_stream((N_R, N_B), batch, 0, 16).simulated.sum()
    with pytest.raises(ValueError, match="before the first results"):
        ref.set_hint(None)


def test_warm_started_point_lists_give_the_same_map_in_any_order():
    """``[settings] warm = true``: each point list seeds its points from the orbits of
    the points before it in the list, and which points share a list depends on the
    arrival order. The labels (hence the refinement) do not: same simulated points and
    regimes as cold point lists in every order; the other fields agree with the cold
    ones to the steady-state tolerance (the fast preset's, on slow points), and between
    two orders far closer (moving orbits polished to their fixed point; here bounded by
    the fast preset's event times, 1e-9; cycles excepted)."""
    scene = Scene("ground", 2)
    r = np.linspace(0.05, 2.5, 80)
    beta = np.linspace(0.0, 1.5, 40)

    def batch(warm):
        def run(i, j):
            res = classify(scene, r[i], beta[j], fidelity="fast", warm=warm, design=True)
            return {k: np.asarray(getattr(res, k)) for k in FIELDS}

        return run

    cold = shuffled_stream((r.size, beta.size), batch(False), 0, 8, dof=2).result()
    warms = []
    for seed in range(2):
        warm = shuffled_stream((r.size, beta.size), batch(True), seed, 8, dof=2).result()
        np.testing.assert_array_equal(warm["simulated"], cold["simulated"])
        for name in ("regime", "converged", "stops_per_cycle", "period", "start_dependent"):
            np.testing.assert_array_equal(warm[name], cold[name], err_msg=name)
        moving = cold["regime"] > regimes.NO_MOTION
        # the fast preset's looser section tolerance (1e-5; slow points: more)
        np.testing.assert_allclose(
            warm["slip_amplitude"][moving], cold["slip_amplitude"][moving], rtol=1e-3
        )
        np.testing.assert_allclose(warm["stick_fraction"], cold["stick_fraction"], atol=1e-4)
        warms.append(warm)
    for name in ("slip_amplitude", "stick_fraction", "dissipation"):
        a, b = warms[0][name], warms[1][name]
        np.testing.assert_array_equal(np.isfinite(a), np.isfinite(b), err_msg=name)
        fin = np.isfinite(a)
        scale = np.abs(a[fin]).max()
        np.testing.assert_allclose(a[fin], b[fin], rtol=0, atol=1e-7 * scale, err_msg=name)
    assert len(set(cold["regime"].ravel().tolist())) >= 2
