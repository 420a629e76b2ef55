"""Steady states that are really steady: creep, several starts, slow points.

Independent truths: the closed-form motion bound (above it the limit of any
motion is no motion, docs/theory.md 4.2), the reference cases of ``tests/data/``
(labelled from the held start and from rest by an independent simulator),
Shaw's uniqueness of SDOF steady states away from r = 1/n (docs/theory.md 3),
and the scaling of the slip amplitude just below the SDOF motion bound.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from analysis import boundaries, predict
from tasks import Scene, classify, kernel, regimes
from tasks.classifier import scene_modes_cached, settings_args
from tasks.fidelity import resolve
from tasks.model import scene_modes
from tasks.scene import CONFIGURATIONS

CONFIGS = CONFIGURATIONS


def _threshold(scene: Scene, beta: np.ndarray) -> np.ndarray:
    """The creep threshold recomputed from its definition (tasks.regimes.SLIP_RTOL)."""
    args = scene_modes(scene).kernel_args()
    K, b = args[1], args[2]
    return regimes.SLIP_RTOL * np.asarray(beta) * float(b @ np.linalg.solve(K, b))


def _cases(path, keep):
    cases = json.loads(path.read_text())["cases"]
    out = []
    for c in cases:
        if not keep(c):
            continue
        g, k = (c["g"][1:], c["k"][1:]) if c["N"] > 1 else (1.0, 1.0)
        scene = Scene(c["contact"], c["N"], c["j"], gamma=g, kappa=k)
        out.append((c, scene))
    return out


@pytest.mark.parametrize("fidelity", ["fast", "balanced", "exact"])
def test_creep_from_rest_is_no_motion_above_the_motion_bound(fidelity):
    """The issue's creep points (2DOF, ground contact on m_2): above the closed-form
    motion bound the limit is no motion, from rest too, with every preset (the
    held margin decides it; `fast`, with its section tolerance of 1e-5, used to
    accept the creep as a converged stick-slip orbit)."""
    scene = Scene("ground", 2, 2)
    r = np.array([0.05, 0.5])
    beta = np.array([0.6, 0.7])
    _, bm = boundaries(scene, r, method="exact")
    assert np.all(beta >= bm)  # the known limit: no motion
    res = classify(scene, r, beta, fidelity=fidelity, initial_condition="rest")
    assert np.all(res.regime == regimes.NO_MOTION), res
    assert np.all(res.asymptotic)  # reached by a creep, not at once
    creep_slip = regimes.CREEP_SLIP_RTOL / regimes.SLIP_RTOL * _threshold(scene, beta)
    assert np.all(res.slip_amplitude < creep_slip)


def test_no_stick_slip_below_the_threshold_from_rest():
    """A low-r strip of the Fig. 5 panel from rest, where creep was common."""
    scene = Scene("ground", 2, 2)
    r, beta = np.meshgrid(np.linspace(0.05, 0.6, 8), np.linspace(0.1, 1.2, 8), indexing="ij")
    res = classify(scene, r, beta, initial_condition="rest")
    tiny = (res.regime == regimes.STICK_SLIP) & (res.slip_amplitude < _threshold(scene, beta))
    assert not tiny.any()
    bm = boundaries(scene, r[:, 0], method="exact")[1][:, None]
    above = (beta >= bm) & (res.regime >= 0)
    assert np.all(res.regime[above] == regimes.NO_MOTION)


def test_genuine_small_stick_slip_follows_the_threshold():
    """SDOF ground, r = 1.5: just below the motion bound beta = 1 the slip amplitude
    is (1 - beta)^2 (measured scaling); stick-slip above the threshold, no motion
    (asymptotic) below it (1e-8 < 1e-7 beta), never stick-slip with a slip below it."""
    scene = Scene("ground", 1)
    delta = np.array([1e-1, 1e-2, 1e-3, 1e-4])
    beta = 1.0 - delta
    res = classify(scene, 1.5, beta)
    tol = _threshold(scene, beta)
    assert np.allclose(res.slip_amplitude[:2], delta[:2] ** 2, rtol=0.3)
    assert np.all(res.regime[res.slip_amplitude >= tol] == regimes.STICK_SLIP)
    assert np.all(res.regime[res.slip_amplitude < tol] == regimes.NO_MOTION)
    assert res.regime[0] == regimes.STICK_SLIP and res.regime[-1] == regimes.NO_MOTION


def test_reference_cases_from_both_starts(reference_cases_path):
    """Held and rest against the independent reference simulator: where it found the
    same regime from both starts (ic_robust) so must we; where it did not converge
    from rest (creep above the motion bound, held: no motion) we reach no motion."""
    pairs = _cases(reference_cases_path, lambda c: c["config"] in CONFIGS)
    assert len(pairs) > 100
    robust = creep = 0
    for c, scene in pairs:
        res = classify(scene, c["r"], c["b"], starts=("held", "rest"))
        assert regimes.name(int(res.regime)) == c["reference_regime"], c["id"]
        if c["ic_robust"]:
            assert regimes.name(int(res.regime_rest)) == c["rest_ic_regime"], c["id"]
            assert not res.start_dependent, c["id"]
            robust += 1
        elif c["reference_regime"] == "no_motion" and not c["rest_ic_converged"]:
            assert int(res.regime_rest) == regimes.NO_MOTION, c["id"]
            creep += 1
    assert robust > 100 and creep >= 10


def test_sdof_steady_state_is_unique_from_random_starts():
    """Shaw: SDOF steady states are unique away from r = 1/n; random starts on the
    energy scale of the forced response all reach the closed-form regime."""
    scene = Scene("ground", 1)
    r = np.array([0.37, 0.8, 1.6, 2.3, 1.6, 0.8])
    beta = np.array([0.2, 0.3, 0.1, 0.5, 0.9, 1.1])
    res = classify(scene, r, beta, starts=("held", "rest"), n_random=3, seed=7)
    assert not res.start_dependent.any()
    assert np.all(res.regime == predict(scene, r, beta, method="exact"))
    assert np.all(res.regimes_reached == (1 << res.regime.astype(int)))


def test_random_starts_are_seeded_and_on_the_energy_scale():
    scene = Scene("ground", 2, 1, gamma=0.5, kappa=2.0)
    args = scene_modes_cached(scene).kernel_args()
    held = settings_args(resolve("balanced"))
    ctx, _, X_held, _, _ = kernel._context(0.7, 0.3, args, held)
    gamma, K = args[0], args[1]
    p = ctx[kernel.CTX_P]
    e_ref = max(kernel._energy(X_held, gamma, K, 0.7), 0.5 * p @ np.linalg.solve(K, p))
    energies = []
    for k in range(6):
        code = regimes.IC_RANDOM + k
        X1 = kernel._context(0.7, 0.3, args, settings_args(resolve("balanced"), code))[2]
        X2 = kernel._context(0.7, 0.3, args, settings_args(resolve("balanced"), code))[2]
        assert np.array_equal(X1, X2)  # seeded: the same start every time
        energies.append(kernel._energy(X1, gamma, K, 0.7))
    assert 0.0 < min(energies) and max(energies) <= 2.0 * e_ref * (1 + 1e-12)
    assert len(set(np.round(energies, 12))) == 6  # different starts
    # the same point gets the same random starts whatever else is classified with it
    a = classify(scene, [0.7], [0.3], n_random=2, starts=("held",))
    b = classify(scene, [0.3, 0.7], [0.9, 0.3], n_random=2, starts=("held",))
    assert a.regimes_reached[0] == b.regimes_reached[1]


@pytest.mark.slow
def test_slow_points_next_to_the_antiresonance_settle():
    """Fig. 4 panel (gamma, kappa) = (0.5, 1): the grid column next to the
    antiresonance r = sqrt(kappa / gamma) ran out of cycles; it settles now, on a
    stable orbit that the plain iteration of the exact preset also reaches."""
    scene = Scene("ground", 2, 1, gamma=0.5, kappa=1.0)
    r = 0.02 + (2.5 - 0.02) * 140 / 249  # the grid column of examples/fig04.toml
    beta = np.array([0.65, 0.75, 0.85])
    res = classify(scene, r, beta)
    assert np.all(res.regime >= 0)
    slow = classify(scene, r, beta, fidelity="exact", shooting=False, max_cycles=60000)
    assert np.all(slow.regime == res.regime)
    assert np.allclose(slow.slip_amplitude, res.slip_amplitude, rtol=1e-3)


@pytest.mark.slow
def test_slow_column_settles_from_another_section_phase():
    """Fig. 4 panel (gamma, kappa) = (1, 0.5), grid column r = 0.70723 next to the
    antiresonance 0.70711: Newton's method fails from the section the iteration
    picks and succeeds, as the last resort after max_cycles, from a section a
    quarter period later (tasks.kernel.settle_at_phases). The settled orbit is the one the plain
    iteration of the exact preset reaches after 15,000-24,000 cycles."""
    scene = Scene("ground", 2, 1, gamma=1.0, kappa=0.5)
    r = 0.02 + (2.5 - 0.02) * 69 / 249
    beta = np.array([0.6061, 0.7576])
    res = classify(scene, r, beta)
    assert np.all(res.regime == regimes.STICK_SLIP)
    # slow: settled after many hundred cycles, the second point by the last resort
    # once the 2000 cycles of balanced were spent
    assert np.all((res.cycles > 1000) & (res.cycles <= 2000 + 4 * kernel.SETTLE_CYCLES))
    assert res.cycles[1] > 2000
    slow = classify(scene, r, beta, fidelity="exact", shooting=False, max_cycles=60000)
    assert np.all(slow.cycles > 5000)  # the plain iteration is slow here
    assert np.array_equal(slow.regime, res.regime)
    assert np.array_equal(slow.stops_per_cycle, res.stops_per_cycle)
    # the same orbit: slip amplitude to 1e-5 (measured 6e-6), stick fraction to 1e-6
    assert np.allclose(slow.slip_amplitude, res.slip_amplitude, rtol=1e-4)
    assert np.allclose(slow.stick_fraction, res.stick_fraction, atol=1e-5)


def test_start_settings_are_validated():
    with pytest.raises(ValueError, match="^starts"):
        resolve("balanced", starts=["held", "sideways"])
    with pytest.raises(ValueError, match="^starts"):
        resolve("balanced", starts=["rest", "rest"])
    with pytest.raises(ValueError, match="^n_random"):
        resolve("balanced", n_random=-1)
    assert resolve("balanced", starts=["held", "rest"]).starts == ("held", "rest")


def test_study_settings_key_for_starts():
    """``[settings] starts`` reaches the Dask task, whose output has the new fields."""
    from study.compute import compute_chunk
    from study.definition import Study

    study = Study.from_dict(
        {
            "settings": {"starts": ["held", "rest"], "n_random": 1},
            "scene": [
                {
                    "name": "s",
                    "contact": "ground",
                    "dof": 2,
                    "contact_mass": 2,
                    "points": [[0.05, 0.6]],
                }
            ],
        }
    )
    settings = study.settings
    assert settings.starts == ("held", "rest") and settings.n_random == 1
    task = {
        "kind": "points",
        "scene": study.scenes[0].base_scene.to_dict(),
        "settings": settings.to_dict(),
        "r": np.array([0.05]),
        "beta": np.array([0.6]),
    }
    out = compute_chunk(task)
    assert out["regime"][0] == regimes.NO_MOTION and out["regime_rest"][0] == regimes.NO_MOTION
    assert not out["start_dependent"][0]
    assert out["regimes_reached"][0] == 1  # no motion from all three starts


def _max_stuck_force_ratio(scene: Scene, r: float, beta: float, fidelity: str) -> float:
    """max |g| / beta over the stick phases of the converged orbit, finely sampled."""
    from tasks import trajectory

    tr = trajectory(scene, r, beta, start="steady", fidelity=fidelity)
    args = scene_modes(scene).kernel_args()
    K, g_load = args[1], args[18]
    p = tr._ctx[kernel.CTX_P]
    taus = np.linspace(tr.tau[0], tr.tau[-1], 20001)
    x, _ = tr.sample(taus)
    phase = tr.mode[np.clip(np.searchsorted(tr.tau, taus, side="right") - 1, 0, tr.mode.size - 1)]
    stuck = phase == 0
    g = (p[None, :] * np.cos(taus[stuck])[:, None] - x[stuck] @ K.T) @ g_load
    return float(np.abs(g).max() / beta) if g.size else 0.0


@pytest.mark.parametrize("fidelity", ["fast", "balanced", "exact"])
def test_low_r_base_m1_orbit_keeps_the_stick_invariant(fidelity):
    """A preset-dependent orbit (2DOF base contact on m_1, gamma = kappa = 1,
    r = 0.5379, beta = 0.1212: `balanced` found 2 stops, `exact` 4) was no
    coexistence: Eq. 79 requires |g| <= beta while stuck, and the 2-stop orbit
    violated it (|g| = 1.37 beta inside a stick phase, a missed unsticking). With
    the complete unsticking search every preset keeps the invariant and finds the
    same orbit."""
    scene = Scene("base", 2, 1)
    r = 0.02 + (2.5 - 0.02) * 52 / 249
    beta = 4.0 * 3 / 99
    assert _max_stuck_force_ratio(scene, r, beta, fidelity) <= 1.0 + 1e-6
    assert classify(scene, r, beta, fidelity=fidelity).stops_per_cycle == (
        classify(scene, r, beta, fidelity="exact").stops_per_cycle
    )


def test_report_maps_where_the_regime_depends_on_the_start(tmp_path):
    """A result with start variables gets a 'Dependence on the start' section and map."""
    import xarray as xr

    from analysis.report import write_report

    r = np.linspace(0.1, 2.0, 6)
    beta = np.linspace(0.0, 1.0, 5)
    regime = np.full((6, 5), regimes.STICK_SLIP, dtype=np.int8)
    dep = np.zeros((6, 5), dtype=bool)
    dep[2, 3] = dep[4, 1] = True
    asym = np.zeros((6, 5), dtype=bool)
    asym[0, 4] = True
    ds = xr.Dataset(
        {
            "regime": (("r", "beta"), regime, regimes.cf_flag_attributes()),
            "start_dependent": (("r", "beta"), dep),
            "asymptotic": (("r", "beta"), asym),
            "regimes_reached": (("r", "beta"), np.where(dep, 6, 2).astype(np.int8)),
        },
        coords={"r": r, "beta": beta},
        attrs={"scene_name": "s", "contact": "ground", "dof": 2, "contact_mass": 1},
    )
    path = tmp_path / "res.nc"
    ds.to_netcdf(path, engine="netcdf4")
    md = write_report(path, tmp_path / "rep").read_text()
    assert "### Dependence on the start" in md
    assert "2 of 30 points reach different regimes" in md
    assert "1 reach no motion asymptotically" in md
    assert (tmp_path / "rep" / "s_starts.png").exists()


def _held_state_and_force(scene: Scene, r: float) -> tuple[np.ndarray, float]:
    """The held steady state at tau = 0 and its contact force amplitude, from the
    scipy integrator's matrices (tasks.baseline), not from the kernel."""
    from tasks import baseline

    sys_ = baseline._system(scene, r)
    M, K, p = scene.mass_matrix(r), scene.stiffness_matrix(), scene.load_vector(r)
    T, _ = scene.stuck_basis()
    x_h = T @ np.linalg.solve(T.T @ (K - M) @ T, T.T @ p)
    return x_h, abs(baseline._contact_force(sys_, 0.0, x_h))


# (scene, r, beta) just above the motion bound, where a run from rest creeps
MARGIN_POINTS = [
    (Scene("ground", 2, 2), 0.5, 0.7),
    (Scene("ground", 2, 2), 0.05, 0.6),
    (Scene("base", 2, 1, gamma=0.5, kappa=2.0), 0.9, None),
    (Scene("mass", 2, gamma=2.0, kappa=0.5), 0.6, None),
]


@pytest.mark.parametrize("case", range(len(MARGIN_POINTS)))
def test_every_start_reaches_no_motion_above_the_held_margin(case):
    """docs/theory.md 3: with delta = beta - max|g_h| > 0, the energy E of the
    difference between any motion and the held steady state never increases
    (dE/dtau <= -delta |v|). Checked on runs from rest of the independent scipy
    integrator (cycle by cycle, tolerances 1e-12); the kernel's margin equals the
    one computed here, and it gives no motion from rest without simulating."""
    from tasks import baseline

    scene, r, beta = MARGIN_POINTS[case]
    x_h, g_h = _held_state_and_force(scene, r)
    if beta is None:
        beta = 1.02 * g_h  # 2 % above the motion bound
    delta = beta - g_h
    assert delta > 0.0
    args = scene_modes_cached(scene).kernel_args()
    ctx = kernel._context(r, beta, args, settings_args(resolve("balanced")))[0]
    assert kernel.held_margin(ctx) == pytest.approx(delta, rel=1e-9, abs=1e-12)
    M, K = scene.mass_matrix(r), scene.stiffness_matrix()
    energies = []
    for cycles in (1, 2, 3, 5, 8):  # each a run from rest: 19 cycles in all
        _, info = baseline.paper_method(scene, r, beta, cycles=cycles, atol=1e-12)
        e, ed = info["x_end"] - x_h, info["xd_end"]  # x_h' = 0 at tau = 2 pi k
        energies.append(0.5 * ed @ M @ ed + 0.5 * e @ K @ e)
    energies = np.array(energies)
    assert energies[0] > 0.0
    assert np.all(np.diff(energies) <= 1e-7 * energies[0]), energies
    res = classify(scene, r, beta, initial_condition="rest")
    assert int(res.regime) == regimes.NO_MOTION and bool(res.asymptotic)
    assert int(res.cycles) == 0  # decided by the margin, not by a creep
    # just below the bound the margin decides nothing: the start is simulated
    below = classify(scene, r, 0.98 * g_h, initial_condition="rest")
    assert int(below.cycles) > 0


def test_periodic_steady_states_share_their_stick_and_slip_intervals():
    """docs/theory.md 3 ("one regime per point"): two periodic steady states of the
    same point stick and slide at the same times, so held and rest starts converge
    to the same regime, stops and stick fraction wherever both settle (2DOF and
    5DOF scenes, in the stick-slip band between the closed-form boundaries)."""
    cases = [
        (Scene("ground", 2, 2), [0.3, 0.8, 1.3, 2.0]),
        (Scene("base", 2, 1, gamma=0.5, kappa=2.0), [0.4, 0.9, 1.5]),
        (Scene("mass", 2, gamma=2.0, kappa=0.5), [0.5, 1.1, 1.8]),
        (Scene("ground", 5, 4), [0.3, 0.7, 1.2]),
    ]
    compared = stick_slip = 0
    for scene, r in cases:
        r = np.repeat(r, 2)
        bc, bm = boundaries(scene, r, method="exact")
        beta = bc + np.tile([0.3, 0.7], r.size // 2) * (bm - bc)
        held = classify(scene, r, beta, fidelity="exact")
        rest = classify(scene, r, beta, fidelity="exact", initial_condition="rest")
        both = (held.regime >= 0) & (rest.regime >= 0)
        assert np.array_equal(held.regime[both], rest.regime[both])
        assert np.array_equal(held.stops_per_cycle[both], rest.stops_per_cycle[both])
        assert np.allclose(held.stick_fraction[both], rest.stick_fraction[both], atol=1e-6)
        compared += int(both.sum())
        stick_slip += int((both & (held.regime == regimes.STICK_SLIP)).sum())
    assert compared >= 20 and stick_slip >= 15, (compared, stick_slip)
