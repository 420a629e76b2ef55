"""Converged orbits are solutions: no stick phase with |g| > beta, no slip phase whose
contact velocity changes sign (issue 14).

* the orbit invariant on every configuration and preset at low r (0.05-0.4, where
  short slips inside long stick phases are easy to miss), checked by dense
  sampling of the exact state (``Trajectory.sample``) with the contact force
  computed from the state (``g = g_load . (p cos tau - K x)``, docs/theory.md 2);
* SDOF orbits against an ODE-free reference written here: the piecewise closed-form
  SDOF solution (docs/theory.md 2, "SDOF") with its own event search (dense
  sampling + ``brentq``), started from the classifier's section state: it must come
  back to that state after one period, with the same stops and amplitude;
* the work budget bounds the time of any point (``step_fraction = 1e-17``).
"""

from __future__ import annotations

import math
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from scipy.optimize import brentq

from tasks import Scene, classify, regimes, trajectory
from tasks.classifier import scene_modes_cached
from tasks.scene import CONFIGURATIONS

CONFIGS = {
    **CONFIGURATIONS,
    "5dof_ground_m3": Scene("ground", 5, 3, gamma=[1.5, 0.7, 1.2, 0.9], kappa=[0.8, 1.3, 1.0, 0.6]),
}
PRESETS = ("fast", "balanced", "exact")
# Points whose converged orbits broke the invariant before issue 14 (found by
# benchmarks/sweep_invariant.py): a stick phase ran through |g| = beta.
MISSED = {
    "sdof_ground": [(1 / 13, 0.0012), (0.13974358974358975, 0.007895198695890808)],
    # SDOF base = SDOF ground with the load scaled by r^2 (docs/theory.md 2)
    "sdof_base": [(1 / 13, 0.0012 / 13**2), (0.13974358974358975, 0.007895198695890808 * 0.01953)],
}
RTOL_G = 1e-6  # |g| <= beta (1 + RTOL_G) through every sampled stick phase
# how closely a converged orbit repeats: 10 x the preset's section_rtol (tasks.fidelity)
RTOL_ORBIT = {"fast": 1e-4, "balanced": 1e-6, "exact": 1e-6}


def invariant(scene: Scene, r: float, beta: float, fidelity: str, samples: int = 3000):
    """``(max |g| / beta over stick phases, slip phases whose velocity changes sign)``."""
    tr = trajectory(scene, r, beta, fidelity=fidelity)
    modes = scene_modes_cached(scene)
    b = scene.contact_vector()
    p = modes.load(r)
    K = scene.stiffness_matrix()
    worst, flips = 0.0, 0
    span = tr.tau[-1] - tr.tau[0]
    for i in range(len(tr.tau) - 1):
        t0, t1 = tr.tau[i], tr.tau[i + 1]
        if not t1 > t0:
            continue
        tau = np.linspace(t0, t1, max(8, int(samples * (t1 - t0) / span)) + 2)[1:-1]
        x, xd = tr.sample(tau)
        if tr.mode[i] == 0:
            g = (p[None, :] * np.cos(tau)[:, None] - x @ K.T) @ modes.g_load
            worst = max(worst, float(np.max(np.abs(g))) / beta)
        else:
            v = xd @ b
            if np.any(tr.mode[i] * v < -1e-9 * max(float(np.max(np.abs(v))), 1e-300)):
                flips += 1
    return worst, flips


def low_r_points(scene: Scene, n_r: int = 6, n_beta: int = 5):
    """A low-r grid, beta from 1e-3 of the held contact force amplitude to past it."""
    modes = scene_modes_cached(scene)
    points = []
    for r in np.linspace(0.05, 0.4, n_r):
        held = trajectory(scene, r, 1e9, start="held", cycles=1)
        tau = np.linspace(0.0, 2 * np.pi, 200)
        x, _ = held.sample(tau)
        g = (modes.load(r)[None, :] * np.cos(tau)[:, None] - x @ scene.stiffness_matrix().T) @ (
            modes.g_load
        )
        g_amp = float(np.max(np.abs(g)))
        points += [(r, b) for b in np.geomspace(1.2e-3 * g_amp, 1.2 * g_amp, n_beta)]
    return points + MISSED.get(next(k for k, v in CONFIGS.items() if v == scene), [])


@pytest.mark.parametrize("fidelity", PRESETS)
@pytest.mark.parametrize("name", list(CONFIGS))
def test_converged_orbits_satisfy_the_invariant(name, fidelity):
    scene = CONFIGS[name]
    points = low_r_points(scene)
    r, beta = np.array(points).T
    res = classify(scene, r, beta, fidelity=fidelity)
    assert res.converged.mean() > 0.9
    bad = []
    ok = res.converged.astype(bool)
    for ri, bi in zip(r[ok], beta[ok], strict=True):
        worst, flips = invariant(scene, ri, bi, fidelity)
        if worst > 1.0 + RTOL_G or flips:
            bad.append((ri, bi, worst, flips))
    assert not bad


# ---------------------------------------------------------------- SDOF reference
class SdofReference:
    """Piecewise closed-form SDOF motion, ``r^2 x'' + x + beta sgn(x') = p cos tau``.

    docs/theory.md 2: ground (p = 1) or base (p = r^2, z coordinates). Sliding with
    sign s, ``x = c1 cos(tau/r) + c2 sin(tau/r) + P cos(tau) - beta s``,
    ``P = p / (1 - r^2)``; stuck, x is frozen while ``|p cos tau - x| <= beta``.
    Events are found by sampling every phase at ``n_per_period`` points per free
    period and refining each sign change with ``brentq`` (no ODE solver, no code
    shared with the kernel).
    """

    def __init__(self, contact: str, r: float, beta: float, n_per_period: int = 400):
        self.r, self.beta = r, beta
        self.p = 1.0 if contact == "ground" else r * r
        self.w = 1.0 / r
        self.P = self.p / (1.0 - r * r)
        self.dt = 2 * np.pi * min(r, 1.0) / n_per_period

    def slip(self, tau0: float, x0: float, v0: float, s: float):
        """``(x(tau), x'(tau))`` of the slip phase from ``(x0, v0)`` at tau0, vectorised."""
        w, P, c = self.w, self.P, -self.beta * s
        c1 = x0 - c - P * math.cos(tau0)
        c2 = (v0 + P * math.sin(tau0)) / w

        def state(tau):
            t = np.asarray(tau) - tau0
            x = c + c1 * np.cos(w * t) + c2 * np.sin(w * t) + P * np.cos(tau)
            v = w * (-c1 * np.sin(w * t) + c2 * np.cos(w * t)) - P * np.sin(tau)
            return x, v

        return state

    def g(self, tau, x):
        return self.p * np.cos(tau) - x

    def _first_root(self, f, t0: float, t_end: float):
        """First sign change of ``f`` after ``t0`` (f > 0 just after t0), or None."""
        tau = np.arange(t0 + 1e-10, t_end + self.dt, self.dt)
        tau[-1] = min(tau[-1], t_end)
        val = f(tau)
        neg = np.nonzero(val <= 0.0)[0]
        if neg.size == 0:
            return None
        k = neg[0]
        if k == 0:
            return tau[0]
        return brentq(f, tau[k - 1], tau[k], xtol=1e-14, rtol=1e-15)

    def run(self, tau0: float, x0: float, v0: float, tau_end: float):
        """Simulate to tau_end; returns (x, v, stops, x samples) at the end."""
        tau, x, v = tau0, x0, v0
        stops = 0
        xs = [x0]
        mode = np.sign(v) if v != 0 else 0.0
        if mode == 0 and abs(self.g(tau, x)) > self.beta:
            mode = np.sign(self.g(tau, x))
        while tau < tau_end - 1e-12:
            if mode == 0:
                xf = x

                def f(t, xf=xf):
                    return self.beta - np.abs(self.g(t, xf))

                t1 = self._first_root(f, tau, tau_end)
                if t1 is None:
                    return x, 0.0, stops, np.array(xs)
                tau = t1
                mode = np.sign(self.g(tau, x))
                v = 0.0
                continue
            state = self.slip(tau, x, v, mode)

            def f(t, state=state, s=mode):
                return s * state(t)[1]

            t1 = self._first_root(f, tau, tau_end)
            grid = np.arange(tau, tau_end if t1 is None else t1, self.dt / 4)
            xs += list(state(grid)[0])
            if t1 is None:
                x, v = (float(u) for u in state(tau_end))
                xs.append(x)
                return x, v, stops, np.array(xs)
            tau = t1
            x = float(state(tau)[0])
            xs.append(x)
            v = 0.0
            if abs(self.g(tau, x)) <= self.beta:
                mode = 0.0
                stops += 1
            else:
                mode = np.sign(self.g(tau, x))
        return x, v, stops, np.array(xs)


SDOF_POINTS = [
    ("ground", 0.138, 0.011),  # issue 14: |g| reached 1.48 beta in a stick phase
    ("ground", 1 / 13, 0.0012),
    ("ground", 0.13974358974358975, 0.007895198695890808),
    ("ground", 0.3, 0.2),
    ("base", 0.138, 0.011 * 0.138**2),
    ("base", 0.25, 0.01),
]


@pytest.mark.parametrize("fidelity", PRESETS)
@pytest.mark.parametrize(("contact", "r", "beta"), SDOF_POINTS)
def test_sdof_orbit_against_closed_form_reference(contact, r, beta, fidelity):
    scene = Scene(contact, 1)
    tr = trajectory(scene, r, beta, fidelity=fidelity)
    res = tr.result
    assert bool(res.converged)
    period = int(res.period)
    ref = SdofReference(contact, r, beta)
    x0, v0 = float(tr.x[0, 0]), float(tr.xd[0, 0])
    x1, v1, stops, xs = ref.run(tr.tau[0], x0, v0, tr.tau[0] + 2 * np.pi * period)
    # the reference comes back to the classifier's section state after the period
    scale = max(np.ptp(xs), 1e-12)
    assert abs(x1 - x0) <= RTOL_ORBIT[fidelity] * scale
    assert abs(v1 - v0) <= RTOL_ORBIT[fidelity] * scale / r
    # the same stops and amplitude (half peak-to-peak of the contact displacement)
    assert stops == int(res.stops_per_cycle)
    assert 0.5 * np.ptp(xs) == pytest.approx(float(res.slip_amplitude), rel=RTOL_ORBIT[fidelity])


# ---------------------------------------------------------------- work budget
def test_work_budget_bounds_a_point_with_tiny_steps():
    """``step_fraction = 1e-17`` made a point run for minutes; the budget ends it.

    The API refuses such a setting (``tasks.fidelity.LIMITS``); the kernel is
    driven directly here, so that its budget, not the validation, is tested.
    """
    code = textwrap.dedent(
        """
        import time
        import numpy as np
        from tasks import Scene, classify, kernel
        from tasks.classifier import scene_modes_cached, settings_args
        from tasks.fidelity import PRESETS
        classify(Scene("ground", 2, 1), 0.5, 0.3)  # load the compiled kernel
        scene_args = scene_modes_cached(Scene("ground", 2, 1)).kernel_args()
        for fidelity in ("fast", "balanced"):
            args = list(settings_args(PRESETS[fidelity]))
            args[1] = 1e-17  # step_fraction, below what the API accepts
            t = time.perf_counter()
            out, _ = kernel.run_points(
                np.array([0.1, 0.5]), np.array([0.3, 0.3]), scene_args, tuple(args)
            )
            codes = [int(c) for c in out[:, kernel.OUT_REGIME]]
            print(fidelity, codes, time.perf_counter() - t)
        """
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=300, check=True
    )
    for line in done.stdout.strip().splitlines():
        fidelity, *rest = line.split(" ", 1)
        codes, seconds = rest[0].rsplit(" ", 1)
        assert codes == f"[{regimes.WORK_LIMIT}, {regimes.WORK_LIMIT}]", line
        assert float(seconds) < 10.0, line
