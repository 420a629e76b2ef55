"""The exact Jacobian of the Poincare map (:mod:`tasks.kernel.monodromy`).

The truth it is checked against is independent of it: central differences of the
simulated map itself (the recorded period followed from perturbed starts,
events located by Newton's method to rounding: :func:`_follow_records`), with
truncation and rounding both far below the tolerance. Checked at the converged
orbits of stick-slip and continuous points of 2DOF and 5DOF ground contacts
(Figs. 4 and 10b), a base-fixed contact, a contact between masses and a
Rayleigh-damped scene; where it cannot carry a record (non-proportional
damping, an event near tangency) it must say so (False) and shooting then takes
the forward differences.
"""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit

from tasks import Scene
from tasks.classifier import scene_modes_cached, settings_args, start_codes
from tasks.fidelity import resolve
from tasks.kernel.batch import run_points_seeded
from tasks.kernel.context import _context
from tasks.kernel.layout import (
    CTX_B,
    CTX_PROJ,
    CTX_T,
    CTX_W,
    N_STATS,
    OUT_CONVERGED,
    OUT_PERIOD,
    OUT_REGIME,
    REC_X,
)
from tasks.kernel.shooting import (
    REC_ROWS,
    _exact,
    _expand,
    _follow_records,
    _period_recorded,
    _phase_of,
    _records_usable,
    _reduce,
)
from tasks.regimes import CONTINUOUS, STICK_SLIP


@njit(cache=False)
def _exact_and_central(r, beta, scene, settings, row, rel_step):
    """At the section state ``row`` (``final`` of run_points): the exact ``dP/dy - I``
    and central differences of the followed map; ``ok`` -1 (record not usable),
    0 (exact refused it), 1 (both computed), -2 (a difference left the pattern)."""
    n = scene[0].shape[0]
    ctx, work, _, _, _ = _context(r, beta, scene, settings)
    b, w, T, proj = ctx[CTX_B], ctx[CTX_W], ctx[CTX_T], ctx[CTX_PROJ]
    mode = int(row[2 * n])
    theta = row[2 * n + 1]
    y0 = _reduce(row[: 2 * n].copy(), mode, b, w, proj)
    X0 = _expand(y0, mode, n, w, T)
    stats = np.zeros(N_STATS)
    rec = np.empty((REC_ROWS, REC_X + 2 * n))
    rec_n = np.zeros(1, dtype=np.int64)
    _period_recorded(X0, _phase_of(X0, mode, b), stats, ctx, work, theta, rec, rec_n)
    dim = y0.shape[0]
    J = np.full((dim, dim), np.nan)
    C = np.full((dim, dim), np.nan)
    nr = rec_n[0]
    if not _records_usable(rec, nr):
        return J, C, -1
    scale = np.max(np.abs(X0))
    if not _exact(y0, mode, rec, nr, ctx, work, J, scale):
        return J, C, 0
    Pp = np.empty(2 * n)
    Pm = np.empty(2 * n)
    for k in range(dim):
        h = rel_step * max(abs(y0[k]), 1e-2 * scale)
        yp = y0.copy()
        ym = y0.copy()
        yp[k] += h
        ym[k] -= h
        okp = _follow_records(_expand(yp, mode, n, w, T), mode, rec, nr, ctx, work, theta, Pp, 0.1)
        okm = _follow_records(_expand(ym, mode, n, w, T), mode, rec, nr, ctx, work, theta, Pm, 0.1)
        if not (okp and okm):
            return J, C, -2
        dp = _reduce(Pp, mode, b, w, proj) - _reduce(Pm, mode, b, w, proj)
        for i in range(dim):
            C[i, k] = dp[i] / (2.0 * h)
        C[k, k] -= 1.0
    return J, C, 1


def _rayleigh_3dof() -> Scene:
    M = np.diag([1.0, 1.5, 0.8])
    K = np.array([[3.0, -1.0, 0.0], [-1.0, 2.5, -1.2], [0.0, -1.2, 1.7]])
    return Scene.from_matrices(
        M, K, [1.0, 0.3, -0.5], ("ground", 1), damping=("rayleigh", 0.05, 0.02)
    )


SCENES = {
    "fig4": (Scene("ground", 2, 1, gamma=1.0, kappa=0.5), 1.5),
    "fig10b": (Scene("ground", 5, 2), 2.0),
    "base 3DOF m2": (Scene("base", 3, 2), 1.5),
    "between masses 2-3 (3DOF)": (Scene("mass", 3, 2), 1.5),
    "Rayleigh damping 3DOF": (_rayleigh_3dof(), 1.5),
}


def _orbits(scene: Scene, beta_max: float, n_r: int = 14, n_beta: int = 8):
    """Converged period-1 orbits of a coarse panel: ``(r, beta, regime, final)`` rows."""
    r, beta = np.meshgrid(
        np.linspace(0.1, 2.5, n_r), np.linspace(0.02, beta_max, n_beta), indexing="ij"
    )
    r, beta = r.ravel().copy(), beta.ravel().copy()
    resolved = resolve("balanced")
    settings = settings_args(resolved, start_codes(resolved)[0])
    args = scene_modes_cached(scene).kernel_args()
    seeds = np.full((r.size, 0), -1, dtype=np.int64)
    out, final, _ = run_points_seeded(r, beta, args, settings, 0, seeds)
    keep = (out[:, OUT_CONVERGED] == 1.0) & (out[:, OUT_PERIOD] == 1.0)
    keep &= (out[:, OUT_REGIME] == STICK_SLIP) | (out[:, OUT_REGIME] == CONTINUOUS)
    return (
        args,
        settings,
        [(r[i], beta[i], int(out[i, OUT_REGIME]), final[i]) for i in np.nonzero(keep)[0]],
    )


@pytest.mark.parametrize("name", list(SCENES))
def test_exact_jacobian_matches_central_differences(name):
    """Exact and central-difference ``dP/dy`` agree to 1e-6 of ``|dP/dy|`` at the
    orbits of every stick-slip and continuous point of a coarse panel (medians far
    below); both regimes are covered on every scene."""
    scene, beta_max = SCENES[name]
    args, settings, orbits = _orbits(scene, beta_max)
    errors = {STICK_SLIP: [], CONTINUOUS: []}
    refused = 0
    for r, beta, regime, row in orbits:
        J, C, ok = _exact_and_central(r, beta, args, settings, row, 1e-6)
        if ok != 1:  # (0: refused near a tangency, as the differences would be)
            refused += ok == 0
            continue
        dP = C + np.eye(C.shape[0])
        errors[regime].append(np.max(np.abs(J - C)) / np.max(np.abs(dP)))
    for regime, errs in errors.items():
        assert len(errs) >= 3, (name, regime, len(errs))
        assert np.median(errs) < 1e-7, (name, regime, np.median(errs))
        assert np.max(errs) < 1e-6, (name, regime, np.max(errs))
    assert refused <= 0.2 * len(orbits), (name, refused, len(orbits))


def test_non_proportional_damping_is_left_to_differences():
    """With a full damping matrix (pairs, docs/structures.md 4.5) the exact Jacobian
    refuses every record (returns False) and shooting keeps its forward differences:
    the moving points still converge."""
    M = np.eye(3)
    K = np.array([[2.0, -1.0, 0.0], [-1.0, 2.0, -1.0], [0.0, -1.0, 1.0]])
    scene = Scene.from_matrices(
        M, K, [1.0, 0.0, 0.0], ("ground", 2), damping=np.diag([0.1, 0.1, 0.5])
    )
    args, settings, orbits = _orbits(scene, 1.0, 8, 6)
    moving = [o for o in orbits if o[2] == STICK_SLIP]
    assert moving
    refused = 0
    for r, beta, _, row in orbits:
        _, _, ok = _exact_and_central(r, beta, args, settings, row, 1e-6)
        assert ok != 1
        refused += ok == 0
    assert refused >= 1
