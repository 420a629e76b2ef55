"""Closed-form boundaries of structures with viscous damping (docs/structures.md 3).

For ``r^2 M x'' + r C x' + K x + beta s b = p cos(tau)`` (Eq. 1.1) with one
contact. With ``C = 0`` every function here equals its undamped counterpart of
:mod:`analysis.closed_form` (docs/theory.md 4.2, 4.3); the tests check it.

* **Motion bound** (docs/structures.md 3.1): the amplitude of the force the held
  contact must carry in the damped held steady state,
  ``|g_load . (p - (K + i C_r) T Q)|``, ``(T^T (K - M_r + i C_r) T) Q = T^T p``
  (``M_r = r^2 M``, ``C_r = r C``). Exact: no motion iff beta >= it.
* **Continuous bound** (docs/structures.md 3.2, Den Hartog's construction with
  damping): the antisymmetric continuous motion with a reversal at tau = 0 is
  the forced response ``Re(Z e^{i(tau + phi)})``, ``Z = (K - M_r + i C_r)^-1 p``,
  plus the response to the constant friction load ``beta b`` on the half period,
  ``beta (K^-1 b + f(tau))``, whose free part ``f`` makes the motion antisymmetric:
  ``y_f(0) = -2 (Phi(pi) + I)^-1 (K^-1 b, 0)`` in the state space, ``Phi`` the
  state transition matrix. With ``u = b . f'(0)`` and ``h(tau) = b . f'(tau) -
  u cos(tau)`` the contact velocity on (0, pi) is ``-X_h sin(tau) + beta h(tau)``,
  ``X_h = sqrt(|Z_b|^2 - beta^2 u^2)``, so the motion exists iff
  ``X_h > beta S_h``, ``S_h = sup h / sin`` (``"exact"``) or its limit at
  tau -> 0 (``"paper"``: only the reversal, the paper's S = 1), and

      beta_continuous = |Z_b| / sqrt(u^2 + S_h^2)                         (3.6)

  (Eq. 53 / Eq. 13 with ``V -> |Z_b|``, ``U -> u``, ``S/m -> S_h``).
* **Den Hartog's single mass** (1931, combined viscous and Coulomb friction):
  :func:`den_hartog_amplitude` and :func:`den_hartog_sdof_terms` give the same
  quantities in closed form for ``r^2 x'' + 2 zeta r x' + x + beta sgn(x') = cos tau``.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import expm, solve

from tasks.scene import Scene

#: Grid points per half period of the fastest state-space mode (then refined).
POINTS_PER_MODE = 48
MAX_POINTS = 20_000


def _matrices(scene: Scene, r: float):
    M = scene.mass_matrix(r)
    C = scene.damping_matrix(r)
    K = scene.stiffness_matrix()
    p = scene.load_vector(r)
    b = scene.contact_vector()
    return M, C, K, p, b


def motion_bound(scene: Scene, r: np.ndarray) -> np.ndarray:
    """Damped motion bound ``beta_motion(r)`` (docs/structures.md 3.1, Eq. 3.2)."""
    r_arr = np.asarray(r, dtype=float)
    out = np.empty(r_arr.size)
    T, _ = scene.stuck_basis()
    G = scene.mass_matrix(1.0)
    b = scene.contact_vector()
    gb = np.linalg.solve(G, b)
    g_load = gb / (b @ gb)
    for k, rk in enumerate(r_arr.ravel()):
        M, C, K, p, _ = _matrices(scene, float(rk))
        D = K - M + 1j * C
        if T.shape[1]:
            Q = solve(T.T @ D @ T, T.T @ p)
            X = T @ Q
        else:
            X = np.zeros(scene.dof, dtype=complex)
        out[k] = abs(g_load @ (p - (K + 1j * C) @ X))
    return out.reshape(r_arr.shape)


def half_period_terms(scene: Scene, r: float) -> dict[str, float]:
    """``|Z_b|``, ``u``, ``S_h`` (sup) and ``S_0`` (its limit at tau -> 0), and
    ``c_b = b . (K^-1 b + f(0))`` of docs/structures.md 3.2 at one ``r``."""
    M, C, K, p, b = _matrices(scene, r)
    n = scene.dof
    Z = solve(K - M + 1j * C, p)
    Zb = complex(b @ Z)
    xc = np.linalg.solve(K, b)
    A = np.zeros((2 * n, 2 * n))
    A[:n, n:] = np.eye(n)
    A[n:, :n] = -np.linalg.solve(M, K)
    A[n:, n:] = -np.linalg.solve(M, C)
    Phi = expm(A * math.pi)
    y0 = -2.0 * np.linalg.solve(Phi + np.eye(2 * n), np.concatenate((xc, np.zeros(n))))
    lam, V = np.linalg.eig(A)
    coef = np.linalg.solve(V, y0.astype(complex))
    d = (b @ V[n:]) * coef  # b . f'(tau) = Re sum_k d_k e^{lam_k tau}
    u = float(np.real(np.sum(d)))

    def h(t):
        t = np.asarray(t, dtype=float)
        e = np.exp(np.multiply.outer(t, lam))
        return np.real(e @ d) - u * np.cos(t)

    def dh(t):  # h'(t) = b . f''(t) + u sin t
        t = np.asarray(t, dtype=float)
        e = np.exp(np.multiply.outer(t, lam))
        return np.real(e @ (lam * d)) + u * np.sin(t)

    s0 = float(dh(0.0))  # lim_{tau -> 0} h / sin
    s_pi = -float(dh(math.pi))  # lim_{tau -> pi} h / sin
    fastest = float(np.max(np.abs(lam.imag))) if lam.size else 1.0
    npts = int(min(MAX_POINTS, max(200, POINTS_PER_MODE * (1.0 + fastest))))
    tt = np.linspace(0.0, math.pi, npts + 2)[1:-1]
    ratio = h(tt) / np.sin(tt)
    k = int(np.argmax(ratio))
    lo, hi = tt[max(k - 1, 0)], tt[min(k + 1, tt.size - 1)]
    best = float(ratio[k])
    if hi > lo:
        from scipy.optimize import minimize_scalar  # here: scipy.optimize costs 0.5 s to import

        res = minimize_scalar(
            lambda t: -float(h(t) / math.sin(t)),
            bounds=(lo, hi),
            method="bounded",
            options={"xatol": 1e-12},
        )
        best = max(best, -float(res.fun))
    c_b = float(b @ xc + b @ np.real(y0[:n]))
    return {
        "Zb": abs(Zb),
        "u": u,
        "S_h": max(best, s0, s_pi),
        "S_0": s0,
        "c_b": c_b,
        "phase": math.atan2(Zb.imag, Zb.real),
    }


def continuous_bound(scene: Scene, r: np.ndarray, method: str = "paper") -> np.ndarray:
    """Damped continuous / stick-slip boundary (docs/structures.md 3.2, Eq. 3.6)."""
    r_arr = np.asarray(r, dtype=float)
    out = np.empty(r_arr.size)
    for k, rk in enumerate(r_arr.ravel()):
        t = half_period_terms(scene, float(rk))
        S = t["S_h"] if method == "exact" else t["S_0"]
        den = math.hypot(t["u"], max(S, 0.0))
        out[k] = t["Zb"] / den if den > 0.0 else math.inf
    return out.reshape(r_arr.shape)


def continuous_amplitude(scene: Scene, r: float, beta: float) -> float:
    """Contact amplitude of the antisymmetric continuous motion (docs/structures.md 3.2,
    Eq. 3.5): ``sqrt(|Z_b|^2 - beta^2 u^2) + beta c_b``; NaN where condition (a) fails."""
    t = half_period_terms(scene, r)
    disc = t["Zb"] ** 2 - (beta * t["u"]) ** 2
    return math.sqrt(disc) + beta * t["c_b"] if disc >= 0.0 else math.nan


def den_hartog_sdof_terms(r: float, zeta: float) -> tuple[float, float, float]:
    """``(D, u, c)`` of one damped mass, ``r^2 x'' + 2 zeta r x' + x = cos tau`` (ground),
    in closed form (docs/structures.md 3.3, Eqs. 3.7-3.9): the forced amplitude
    ``D = 1 / sqrt((1 - r^2)^2 + (2 zeta r)^2)``, the reversal term ``u = f'(0)`` and
    the offset ``c = 1 + f(0)`` of the friction-driven half-period response
    ``f = e^{-sigma tau} (a cos(w tau) + b sin(w tau))``, ``sigma = zeta / r``,
    ``w = sqrt(1 - zeta^2) / r`` (``0 <= zeta < 1``)."""
    sigma = zeta / r
    w = math.sqrt(1.0 - zeta * zeta) / r
    E = math.exp(-sigma * math.pi)
    c, s = math.cos(w * math.pi), math.sin(w * math.pi)
    # f(pi) + f(0) = -2, f'(pi) + f'(0) = 0 (antisymmetry with the static part 1)
    m11, m12 = 1.0 + E * c, E * s
    m21 = -sigma * (1.0 + E * c) - w * E * s
    m22 = w * (1.0 + E * c) - sigma * E * s
    det = m11 * m22 - m12 * m21
    a = -2.0 * m22 / det
    bb = 2.0 * m21 / det
    D = 1.0 / math.hypot(1.0 - r * r, 2.0 * zeta * r)
    return D, -sigma * a + w * bb, 1.0 + a


def den_hartog_amplitude(r: float, beta: float, zeta: float) -> float:
    """Den Hartog's amplitude of one mass with viscous and Coulomb friction in
    continuous motion (Eq. 3.9): ``sqrt(D^2 - beta^2 u^2) + beta c``; NaN if no
    such motion (condition (a))."""
    D, u, c = den_hartog_sdof_terms(r, zeta)
    disc = D * D - (beta * u) ** 2
    return math.sqrt(disc) + beta * c if disc >= 0.0 else math.nan
