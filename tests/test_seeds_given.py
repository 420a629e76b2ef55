"""Seeds from outside a call: an adaptive map's new point lists are warm-started from
the orbits of solved points near them (tasks.seeds, tasks.classifier.classify_given,
tasks.orbits.Orbits). The labels are those of the held start, the other fields
agree with a call without them to the polish, and only ``cycles`` shows the seeds."""

from __future__ import annotations

import numpy as np

from tasks import Scene, classify, regimes
from tasks.classifier import classify_given
from tasks.result import DESIGN_FIELDS, FIELDS
from tasks.seeds import first_true, grid_neighbours, grid_offsets, warm_seeds

#: Fields that agree only to the polish between differently seeded searches.
CONTINUOUS_FIELDS = ("slip_amplitude", "stick_fraction", *DESIGN_FIELDS)


def test_given_points_rank_with_earlier_points_by_distance():
    r = np.array([1.0, 1.0, 1.0])
    beta = np.array([0.5, 0.56, 0.0])
    given_r = np.array([1.0, 0.2, 1.0])
    given_beta = np.array([0.55, 0.5, 0.505])
    seeds = warm_seeds(r, beta, 2.6, given_r, given_beta)
    # point 0: no earlier point; given 2 (ln beta 0.01 away) before given 0 (0.095)
    assert list(seeds[0, :2]) == [-2 - 2, -2 - 0] and (seeds[0, 2:] == -1).all()
    # point 1: given 0 (0.018), earlier point 0 (0.113), given 2 (0.103): nearest first
    assert list(seeds[1, :3]) == [-2 - 0, -2 - 2, 0]
    assert (seeds[2] == -1).all()  # beta = 0: never seeded
    assert -2 - 1 not in seeds  # r = 0.2: the fastest mode's phase moves too much
    # without given points: the seeds of the call alone, as before
    np.testing.assert_array_equal(
        warm_seeds(r, beta, 2.6, np.zeros(0), np.zeros(0)), warm_seeds(r, beta, 2.6)
    )


def test_grid_neighbours_are_the_nearest_solved_points():
    shape = (9, 9)
    row = np.full(81, -1, dtype=np.int64)
    solved = {(4, 2): 0, (4, 6): 1, (0, 0): 2, (8, 8): 3}
    for (i, j), k in solved.items():
        row[i * 9 + j] = k
    off = grid_offsets(4)
    assert tuple(off[0]) in {(1, 0), (-1, 0), (0, 1), (0, -1)}  # axis neighbours first
    assert len({tuple(o) for o in off}) == len(off) and not (off == 0).all(axis=1).any()
    near = grid_neighbours(np.array([4 * 9 + 4, 0 * 9 + 1, 8 * 9 + 4]), shape, row, off, 2)
    assert sorted(near[0]) == [0, 1]  # the middle of the edge between the two corners
    assert near[1, 0] == 2  # one step away; then the next nearest at a power-of-two offset
    # (8, 8) four steps along beta first, then a corner at (-4, -2) or (-4, 2)
    assert near[2, 0] == 3 and near[2, 1] in (0, 1)
    far = grid_neighbours(np.array([2 * 9 + 5]), shape, row, off, 2)
    assert far[0, 0] == 1 and far[0, 1] == -1  # (4, 6) at (2, 1); no other on the offsets


def test_first_true_keeps_the_stable_argsort_order():
    """The first k kept entries of each row, padded with -1: what a stable argsort of
    the refused entries selects (the formula it replaced, an independent truth)."""
    rng = np.random.default_rng(3)
    for cols, k in ((16, 4), (16, 8), (3, 8), (120, 4)):
        ok = rng.random((200, cols)) < 0.3
        values = rng.integers(-9, 1000, (200, cols))
        first = np.argsort(~ok, axis=1, kind="stable")[:, :k]
        want = np.where(np.take_along_axis(ok, first, 1), np.take_along_axis(values, first, 1), -1)
        np.testing.assert_array_equal(first_true(ok, values, k), want)


def test_given_orbits_seed_the_same_labels_and_fields():
    """A coarse lattice solved first; the points between its nodes classified in small
    lists seeded from it give the labels of ``classify`` and its fields to the polish,
    in fewer periods."""
    scene = Scene("ground", 2, 1, gamma=1.0, kappa=0.5)
    r_axis, beta_axis = np.linspace(0.3, 2.5, 41), np.linspace(0.05, 1.5, 21)
    r, beta = (a.ravel() for a in np.meshgrid(r_axis, beta_axis, indexing="ij"))
    coarse = np.zeros((41, 21), dtype=bool)
    coarse[::2, ::2] = True
    coarse = coarse.ravel()
    solved, final = classify_given(scene, r[coarse], beta[coarse], None, design=True)
    moving = solved.regime > regimes.NO_MOTION
    orbit = np.isfinite(final).all(axis=1)
    # an orbit is kept exactly where the point converged to a moving period-1 motion
    np.testing.assert_array_equal(orbit, moving & solved.converged & (solved.period == 1))
    assert orbit.sum() > 20
    given = (r[coarse][orbit], beta[coarse][orbit], final[orbit])
    rest = np.flatnonzero(~coarse)
    lists = [rest[k::12] for k in range(12)]  # scattered lists: few seeds within a list
    seeded = [classify_given(scene, r[p], beta[p], given, design=True)[0] for p in lists]
    alone = [classify(scene, r[p], beta[p], design=True) for p in lists]
    for name in FIELDS:
        a = np.concatenate([np.asarray(getattr(x, name)) for x in seeded])
        b = np.concatenate([np.asarray(getattr(x, name)) for x in alone])
        if name == "cycles":
            assert a.sum() < 0.85 * b.sum()  # the given orbits were used (26 % fewer)
            continue
        if name not in CONTINUOUS_FIELDS:
            np.testing.assert_array_equal(a, b, err_msg=name)
            continue
        np.testing.assert_array_equal(np.isfinite(a), np.isfinite(b), err_msg=name)
        fin = np.isfinite(a)
        scale = np.abs(b[fin]).max()
        np.testing.assert_allclose(a[fin], b[fin], rtol=0, atol=1e-9 * scale, err_msg=name)
    assert len({int(x) for x in np.concatenate([s.regime for s in seeded])}) >= 2


def test_without_warm_starts_no_orbit_is_given_back():
    scene = Scene("ground", 2, 1, gamma=1.0, kappa=0.5)
    r, beta = np.linspace(0.5, 2.0, 8), np.full(8, 0.3)
    res, final = classify_given(scene, r, beta, None, warm=False)
    assert np.isnan(final).all()
    np.testing.assert_array_equal(res.regime, classify(scene, r, beta, warm=False).regime)


STUDY = """
[study]
name = "seeded"
fidelity = "fast"

[settings]
design = true  # dissipation compared too

[[scene]]
name = "plane"
contact = "ground"
dof = 2
mode = "adaptive"
coarse_step = 8
verify_fraction = 0.01
r = {start = 0.1, stop = 2.4, num = 129}
beta = {start = 0.0, stop = 1.5, num = 65}
"""


def test_study_point_lists_seeded_from_corners_give_the_same_map(tmp_path, monkeypatch):
    """An adaptive study (threads of this process) with its point lists seeded from the
    solved orbits of their cells' corners (the default) and without
    (``AdaptivePlan.seed_lists = False``): the same simulated points and labels, the
    other fields to the polish, fewer periods with the seeds."""
    import io

    import xarray as xr

    from study import Study, run_study
    from study.adaptive import AdaptivePlan

    path = tmp_path / "seeded.toml"
    path.write_text(STUDY, encoding="utf-8")
    maps = {}
    for seeded in (True, False):
        monkeypatch.setattr(AdaptivePlan, "seed_lists", seeded)
        out = tmp_path / f"seeded-{seeded}.nc"
        run_study(Study.from_toml(path), out, progress=False, stream=io.StringIO())
        with xr.open_dataset(out) as ds:
            maps[seeded] = {k: ds[k].values for k in ds.data_vars}
    seeded, alone = maps[True], maps[False]
    sim = alone["simulated"]
    np.testing.assert_array_equal(seeded["simulated"], sim)
    assert 0.05 < sim.mean() < 0.5
    for name in ("regime", "converged", "stops_per_cycle", "period", "asymptotic"):
        np.testing.assert_array_equal(seeded[name], alone[name], err_msg=name)
    assert len(set(alone["regime"][sim].tolist())) >= 2
    for name in ("slip_amplitude", "stick_fraction", "dissipation"):
        a, b = seeded[name][sim], alone[name][sim]
        np.testing.assert_array_equal(np.isfinite(a), np.isfinite(b), err_msg=name)
        fin = np.isfinite(a)
        # the fast preset's event times bound the polish (1e-7 of scale: docs/api.md)
        np.testing.assert_allclose(
            a[fin], b[fin], rtol=0, atol=1e-7 * np.abs(b[fin]).max(), err_msg=name
        )
    cycles_seeded, cycles_alone = seeded["cycles"][sim].sum(), alone["cycles"][sim].sum()
    assert cycles_seeded < 0.9 * cycles_alone  # 19 % fewer here, (cycles_seeded, cycles_alone)
