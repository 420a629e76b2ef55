"""An independent reference for several contacts: scipy's integrator with events.

Nothing here shares code with the compiled simulator beyond the scene: the
motion is propagated in the full coordinates ``x`` by the matrix exponential of
the state space ``(x, x', cos tau, sin tau, 1)`` (exact for each linear phase;
scanned in steps of a 32nd of the fastest half-period, events by brentq) with
the stuck contacts' forces as Lagrange multipliers,

    r^2 G x'' = f - B_S g_S,   g_S = (B_S^T G^-1 B_S)^-1 B_S^T G^-1 f,
    f = p cos(tau) - K x - r C x' - sum_(c sliding) beta_c s_c b_c,

with events at ``b_c . x' = 0`` (sliding c) and ``|g_c| = beta_c`` (stuck c). The
set after an event is chosen by the rule of docs/contacts.md 3 written
afresh (plain numpy enumeration). The held start solves the KKT system
``[[K - r^2 G + i r C, B], [B^T, 0]]`` (complex amplitudes; C = 0 undamped).
Cycles run until the section state repeats (period 1 or 2, relative 1e-7) or
``max_cycles``; every 15 cycles scipy's ``root`` seeks the fixed point of the
Poincare map (taken only where it attracts). Each contact's regime is read from
the last period (stuck throughout: no motion; stuck for more than 1e-6 at a
time: stick-slip, unless its slip amplitude, half the range of ``b_c . x``, is
below the creep threshold ``SLIP_RTOL beta_c c_c`` of docs/contacts.md 4 (``c_c`` the compliance
contact c sees at the excitation frequency: ``b_c^T K^-1 b_c`` below the natural
frequencies, the inertial one above): no motion; else
continuous). Slow (a pure Python loop): for tests and benchmarks only.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
from scipy.linalg import eigh, expm
from scipy.optimize import brentq, root

from tasks import regimes
from tasks.multicontact.scene import MultiScene

SECTION_RTOL = 1e-7
STICK_MIN = 1e-6
#: Slow transients: a root of the Poincare map is sought every SHOOT_EVERY cycles
#: and taken when its residual is below SHOOT_RTOL of the motion (and it attracts).
SHOOT_EVERY = 15
SHOOT_RTOL = 1e-10


class _System:
    def __init__(self, scene: MultiScene, r: float, beta: float):
        self.G = scene.mass_matrix(1.0)
        self.Ginv = np.linalg.inv(self.G)
        self.K = scene.stiffness_matrix()
        self.rC = scene.damping_matrix(r)
        self.B = scene.contact_vectors()
        self.p = scene.load_vector(r)
        self.r2 = r * r
        self.betas = np.array(scene.beta_ratio) * beta
        self.n, self.k = self.B.shape
        self.operators = {}

    def forces(self, tau, x, xd, stuck, signs):
        """``(f - B_S g_S, g)``: the net force and the stuck contacts' forces."""
        f = self.p * math.cos(tau) - self.K @ x - self.rC @ xd
        for c in range(self.k):
            if c not in stuck:
                f = f - self.betas[c] * signs[c] * self.B[:, c]
        g = np.zeros(self.k)
        if stuck:
            Bs = self.B[:, list(stuck)]
            gs = np.linalg.solve(Bs.T @ self.Ginv @ Bs, Bs.T @ self.Ginv @ f)
            g[list(stuck)] = gs
            f = f - Bs @ gs
        return f, g

    def decide(self, tau, x, xd, candidates, signs):
        """Fewest sliding candidates first; stuck |g| <= beta, sliding s a > 0."""
        best = None
        for n_slide in range(len(candidates) + 1):
            for sliding in itertools.combinations(candidates, n_slide):
                for sg in itertools.product((1.0, -1.0), repeat=n_slide):
                    trial = dict(signs)
                    trial.update(dict(zip(sliding, sg, strict=True)))
                    stuck = tuple(c for c in candidates if c not in sliding)
                    f, g = self.forces(tau, x, xd, stuck, trial)
                    a = self.B.T @ (self.Ginv @ f)
                    ok = all(abs(g[c]) <= self.betas[c] for c in stuck)
                    ok = ok and all(trial[c] * a[c] > 0.0 for c in sliding)
                    if ok:
                        return stuck, trial
                    viol = max(
                        [abs(g[c]) - self.betas[c] for c in stuck]
                        + [-trial[c] * a[c] for c in sliding]
                        + [-np.inf]
                    )
                    if best is None or viol < best[0]:
                        best = (viol, stuck, trial)
        return best[1], best[2]

    def held(self):
        """The held start at tau = 0, ``(x, x')``: KKT of the held forced response
        ``x = Re(X e^(i tau))``."""
        active = [c for c in range(self.k) if self.betas[c] > 0.0]
        Ba = self.B[:, active]
        m = len(active)
        D = self.K - self.r2 * self.G + 1j * self.rC
        A = np.block([[D, Ba], [Ba.T, np.zeros((m, m))]])
        rhs = np.concatenate([self.p, np.zeros(m)])
        X = np.linalg.solve(A, rhs)[: self.n]
        return np.concatenate([X.real, -X.imag])


def _operator(sys: _System, stuck, signs):
    """``z' = A z`` for ``z = (x, x', cos tau, sin tau, 1)``, and the event rows:
    ``E z`` gives every contact's force (stuck) or velocity (sliding)."""
    n, k = sys.n, sys.k
    H = np.zeros((k, n))
    P = np.eye(n)
    if stuck:
        Bs = sys.B[:, list(stuck)]
        Hs = np.linalg.solve(Bs.T @ sys.Ginv @ Bs, Bs.T @ sys.Ginv)
        H[list(stuck)] = Hs
        P = P - Bs @ Hs
    fslide = np.zeros(n)
    for c in range(k):
        if c not in stuck:
            fslide -= sys.betas[c] * signs.get(c, 0.0) * sys.B[:, c]
    m = 2 * n + 3
    A = np.zeros((m, m))
    A[:n, n : 2 * n] = np.eye(n)
    GP = sys.Ginv @ P / sys.r2
    A[n : 2 * n, :n] = -GP @ sys.K
    A[n : 2 * n, n : 2 * n] = -GP @ sys.rC
    A[n : 2 * n, 2 * n] = GP @ sys.p
    A[n : 2 * n, 2 * n + 2] = GP @ fslide
    A[2 * n, 2 * n + 1] = -1.0  # (cos)' = -sin
    A[2 * n + 1, 2 * n] = 1.0  # (sin)' = cos
    E = np.zeros((k, m))
    for c in range(k):
        if c in stuck:
            E[c, :n] = -H[c] @ sys.K
            E[c, n : 2 * n] = -H[c] @ sys.rC
            E[c, 2 * n] = H[c] @ sys.p
            E[c, 2 * n + 2] = H[c] @ fslide
        else:
            E[c, n : 2 * n] = sys.B[:, c]
    omega = np.sqrt(np.abs(np.linalg.eigvals(A[n : 2 * n, :n]))).max(initial=1.0)
    if np.any(sys.rC):  # damped: the fastest rate of the state space, decay included
        omega = max(omega, np.abs(np.linalg.eigvals(A[: 2 * n, : 2 * n])).max(initial=1.0))
    h = math.pi / (32.0 * max(omega, 1.0))
    return A, E, h, expm(A * h)


def _event_values(sys, E, z, stuck, signs):
    y = E @ z
    out = np.full(sys.k, np.inf)
    for c in range(sys.k):
        if sys.betas[c] == 0.0:
            continue
        out[c] = sys.betas[c] - abs(y[c]) if c in stuck else signs[c] * y[c]
    return out


def _phase(sys: _System, tau0, tau1, y0, stuck, signs):
    """Exact propagation by the matrix exponential (scanned in steps of a 32nd of
    the fastest half-period, roots by brentq); ``(tau, y, fired contacts)``."""
    n = sys.n
    key = (tuple(stuck), tuple(signs.get(c, 0.0) for c in range(sys.k)))
    if key not in sys.operators:
        sys.operators[key] = _operator(sys, stuck, signs)
    A, E, h, step = sys.operators[key]
    z = np.concatenate([y0, [math.cos(tau0), math.sin(tau0), 1.0]])
    f0 = _event_values(sys, E, z, stuck, signs)
    over = [c for c in stuck if f0[c] < -1e-12 * sys.betas[c]]
    if over:  # a stuck contact already past its limit: decide again at once
        return tau0, y0, over
    t = 0.0
    total = tau1 - tau0
    while t < total:
        dt = min(h, total - t)
        z1 = step @ z if dt == h else expm(A * dt) @ z
        f1 = _event_values(sys, E, z1, stuck, signs)
        crossing = [c for c in range(sys.k) if f0[c] > 0.0 and f1[c] <= 0.0]
        if crossing:
            roots = []
            for c in crossing:

                def fc(u, c=c, z=z):
                    return _event_values(sys, E, expm(A * u) @ z, stuck, signs)[c]

                root = brentq(fc, 0.0, dt, xtol=1e-14, rtol=1e-15)
                # the far side of the zero (the event function <= 0), where the
                # decision is taken: at an unsticking |g| = beta leaves a = 0
                # (1e-10 past the zero: the slip acceleration, 0 at the zero of an
                # unsticking, then stands well above the rounding of the forces)
                root = min(dt, root + 1e-10)
                while fc(root) >= 0.0 and root < dt:
                    root = min(dt, root + 1e-10)
                roots.append(root)
            u = min(roots)
            fired = [c for c, rt in zip(crossing, roots, strict=True) if rt <= u + 1e-9]
            z = expm(A * u) @ z
            return tau0 + t + u, z[: 2 * n], fired
        z, f0, t = z1, f1, t + dt
    return tau1, z[: 2 * n], []


def _cycle(sys: _System, y, stuck, signs, stats):
    """One period from tau = 0; per contact: stuck time, sticks, range of ``b_c . x``
    (its extremes are phase ends: a sliding contact's velocity keeps its sign)."""
    n = sys.n
    tau = 0.0
    stick_start = {c: (0.0 if c in stuck else None) for c in range(sys.k)}
    d0 = sys.B.T @ y[:n]
    for c in range(sys.k):
        stats[c]["dmin"] = stats[c]["dmax"] = d0[c]
    for _ in range(10000):
        t1, y1, fired = _phase(sys, tau, 2 * math.pi, y, stuck, signs)
        d1 = sys.B.T @ y1[:n]
        for c in range(sys.k):
            stats[c]["dmin"] = min(stats[c]["dmin"], d1[c])
            stats[c]["dmax"] = max(stats[c]["dmax"], d1[c])
            if c in stuck:
                stats[c]["stuck"] += t1 - tau
        if not fired or t1 >= 2 * math.pi - 1e-12:
            y = y1
            tau = 2 * math.pi
            break
        # contacts at zero velocity: the stuck ones and those whose event fired
        vel = sys.B.T @ y1[n:]
        cand = sorted(set(stuck) | set(fired))
        free = {c: signs[c] for c in range(sys.k) if c not in cand}
        for c in range(sys.k):
            if c in free and abs(vel[c]) < 1e-9 * (1 + np.abs(y1[n:]).max()):
                cand.append(c)
                free.pop(c)
        cand = [c for c in cand if sys.betas[c] > 0.0]
        # a contact without friction that fired slides on with no force (sign 0)
        free.update({c: 0.0 for c in range(sys.k) if c not in cand and c not in free})
        new_stuck, new_signs = sys.decide(t1, y1[:n], y1[n:], cand, free)
        for c in range(sys.k):
            if c in stuck and c not in new_stuck:
                start = stick_start[c]
                if start is None or t1 - start > STICK_MIN:
                    stats[c]["sticks"] += 1
                stick_start[c] = None
            if c in new_stuck and c not in stuck:
                stick_start[c] = t1
        stuck, signs = tuple(new_stuck), {c: new_signs.get(c, 0.0) for c in range(sys.k)}
        y, tau = y1, t1
    for c in range(sys.k):
        if c in stuck and stick_start[c] is not None and stick_start[c] > 0.0:
            if 2 * math.pi - stick_start[c] > STICK_MIN:
                stats[c]["sticks"] += 1
    return y, stuck, signs


def reference_regimes(
    scene: MultiScene, r: float, beta: float, max_cycles: int = 300
) -> tuple[np.ndarray, bool]:
    """Per-contact regimes of one point (held start) and whether it converged."""
    regime, _, ok = reference_point(scene, r, beta, max_cycles)
    return regime, ok


def reference_point(
    scene: MultiScene, r: float, beta: float, max_cycles: int = 300
) -> tuple[np.ndarray, np.ndarray, bool]:
    """Per-contact regimes and slip amplitudes (half the range of ``b_c . x`` over the
    last period; NaN unconverged) of one point (held start), and whether it converged."""
    sys = _System(scene, r, beta)
    k = sys.k
    if not np.any(sys.betas > 0.0):
        return np.full(k, regimes.CONTINUOUS), np.full(k, np.nan), True
    y = sys.held()
    x0 = y[: sys.n]
    active = [c for c in range(k) if sys.betas[c] > 0.0]
    stuck, signs = sys.decide(
        0.0, x0, y[sys.n :], active, {c: 0.0 for c in range(k) if c not in active}
    )
    signs = {c: signs.get(c, 0.0) for c in range(k)}
    history = []
    for cycle in range(max_cycles):
        if cycle and cycle % SHOOT_EVERY == 0:
            y = _shoot(sys, y, tuple(stuck), dict(signs))
        stats = [{"stuck": 0.0, "sticks": 0} for _ in range(k)]
        key = (tuple(stuck), tuple(signs[c] for c in range(k)))
        y_new, stuck, signs = _cycle(sys, y.copy(), tuple(stuck), dict(signs), stats)
        history.append((y.copy(), key, stats))
        y = y_new
        scale = max(np.abs(y).max(), 1e-300)
        now = (tuple(stuck), tuple(signs[c] for c in range(k)))
        for period in (1, 2):
            if len(history) >= period + 2:
                y_old, key_old, _ = history[-period]
                if key_old == now and np.abs(y - y_old).max() <= SECTION_RTOL * scale:
                    return (*_regimes(history[-period:], sys), True)
    return np.full(k, regimes.NOT_CONVERGED), np.full(k, np.nan), False


def _shoot(sys: _System, y, stuck, signs):
    """A slow transient: scipy's ``root`` on ``P(y) - y`` (one period, the section's
    stuck set and signs kept). The root is taken only if its residual is below
    ``SHOOT_RTOL`` of the motion, the period from it ends in the same set and
    signs, every sliding contact moves in its slip direction there, and it
    attracts (spectral radius of the difference Jacobian of ``P`` at most
    1 + 1e-6); else ``y`` comes back unchanged."""
    key = (stuck, tuple(signs[c] for c in range(sys.k)))

    def period(v):
        stats = [{"stuck": 0.0, "sticks": 0} for _ in range(sys.k)]
        v1, st, sg = _cycle(sys, v.copy(), stuck, dict(signs), stats)
        return v1, (tuple(st), tuple(sg.get(c, 0.0) for c in range(sys.k)))

    sol = root(lambda v: period(v)[0] - v, y, method="hybr", options={"xtol": 1e-13})
    v = sol.x
    if not np.all(np.isfinite(v)):
        return y
    v1, key1 = period(v)
    scale = max(np.abs(v).max(), 1e-300)
    if key1 != key or np.abs(v1 - v).max() > SHOOT_RTOL * scale:
        return y
    # every sliding contact must move in its slip direction at the section (a root
    # with a velocity of the wrong sign, or at rest, is no motion of this map)
    vel = sys.B.T @ v[sys.n :]
    for c in range(sys.k):
        if c not in stuck and sys.betas[c] > 0.0 and signs[c] * vel[c] <= 1e-9 * scale:
            return y
    h = 1e-7 * scale
    jac = np.empty((v.size, v.size))
    for i in range(v.size):
        vp = v.copy()
        vp[i] += h
        jac[:, i] = (period(vp)[0] - v1) / h
    if np.abs(np.linalg.eigvals(jac)).max() > 1.0 + 1e-6:
        return y
    return v


def _regimes(history, sys: _System) -> tuple[np.ndarray, np.ndarray]:
    out = np.empty(sys.k, dtype=int)
    amplitudes = np.empty(sys.k)
    span = 2 * math.pi * len(history)
    compliance = np.einsum("ik,ik->k", sys.B, np.linalg.solve(sys.K, sys.B))
    if np.any(sys.rC):  # damped: static or inertial, the smaller
        inertial = np.einsum("ik,ik->k", sys.B, sys.Ginv @ sys.B) / sys.r2
    else:  # each mode answers with its spring below resonance, its inertia above
        lam, psi = eigh(sys.K, sys.G)
        inertial = ((sys.B.T @ psi) ** 2 / np.maximum(lam, sys.r2)).sum(axis=1)
    compliance = np.minimum(compliance, inertial)
    for c in range(sys.k):
        amplitude = 0.5 * (
            max(h[2][c]["dmax"] for h in history) - min(h[2][c]["dmin"] for h in history)
        )
        amplitudes[c] = amplitude
        if sys.betas[c] == 0.0:
            out[c] = regimes.CONTINUOUS
            continue
        stuck = sum(h[2][c]["stuck"] for h in history)
        sticks = sum(h[2][c]["sticks"] for h in history)
        if stuck >= span - 1e-6:
            out[c] = regimes.NO_MOTION
        elif amplitude < regimes.SLIP_RTOL * sys.betas[c] * compliance[c]:
            out[c] = regimes.NO_MOTION  # below the creep threshold (docs/contacts.md 4)
        elif sticks > 0 or stuck > STICK_MIN:
            out[c] = regimes.STICK_SLIP
        else:
            out[c] = regimes.CONTINUOUS
    return out, amplitudes


def agreement(scene: MultiScene, r, beta, regime, converged, max_cycles: int = 600):
    """Per-contact regimes of the simulator (``regime`` (n, k), ``converged`` (n,),
    at the points ``r``, ``beta``) against :func:`reference_regimes`, compared
    where both reached a steady state. Returns ``(compared, agreed, misses,
    unconverged)``: regimes compared and equal, the differences as
    ``(r, beta, contact, simulator, reference)``, points the reference left
    unconverged."""
    compared = agreed = unconverged = 0
    misses = []
    for i in range(len(r)):
        ref, ok = reference_regimes(scene, float(r[i]), float(beta[i]), max_cycles)
        unconverged += int(not ok)
        if not (ok and converged[i]):
            continue
        for c in range(scene.n_contacts):
            compared += 1
            if ref[c] == regime[i][c]:
                agreed += 1
            else:
                misses.append((float(r[i]), float(beta[i]), c, int(regime[i][c]), int(ref[c])))
    return compared, agreed, misses, unconverged


def random_structure(rng: np.random.Generator, n: int):
    """A random structure no one tuned the code on: symmetric positive definite
    full ``M = I + 0.3 A A^T / n`` and ``K = C C^T + n I / 2`` (A, C standard
    normal) and a standard normal load."""
    A = rng.normal(size=(n, n))
    M = np.eye(n) + 0.3 * (A @ A.T) / n
    C = rng.normal(size=(n, n))
    K = C @ C.T + 0.5 * n * np.eye(n)
    return M, K, rng.normal(size=n)


def held_structure(M, K, p, contact):
    """The structure with ``contact`` held (``("ground", j)``: row and column j
    removed; ``("between", i, j)``: DOFs i and j merged into one coordinate at
    the place of the first), written out by hand: ``(M', K', p', index)``,
    ``index[i]`` the coordinate DOF i becomes (-1 for a removed one)."""
    n = M.shape[0]
    if contact[0] == "ground":
        keep = [i for i in range(n) if i != contact[1]]
        index = np.array([keep.index(i) if i in keep else -1 for i in range(n)])
        return M[np.ix_(keep, keep)], K[np.ix_(keep, keep)], p[keep], index
    a, b = sorted(contact[1:])
    keep = [i for i in range(n) if i != b]
    T = np.zeros((n, n - 1))
    for col, i in enumerate(keep):
        T[i, col] = 1.0
    T[b, keep.index(a)] = 1.0
    index = np.array([keep.index(a if i == b else i) for i in range(n)])
    return T.T @ M @ T, T.T @ K @ T, T.T @ p, index


#: The seed of the agreement draw (benchmarks/bench_multicontact_reference.py and
#: its cheap subset in tests/test_multicontact_reference.py).
DRAW_SEED = 2026


def draw_scenes(seed: int = DRAW_SEED) -> list[tuple[str, MultiScene]]:
    """Scenes for the agreement with the simulator, none tuned on: chains (walls,
    a wall and a contact between masses, base excitation) and random full M, K
    (2, 3 and 4 DOF, up to three contacts); random ratios, beta_ratio in 0.3..1.5."""
    rng = np.random.default_rng(seed)

    def ratio(k):
        return list(rng.uniform(0.3, 1.5, k))

    def chain(kind, dof, masses):
        g, kp = (list(rng.uniform(0.5, 2.0, dof - 1)) for _ in range(2))
        return MultiScene.chain(kind, dof, masses, g, kp, ratio(len(masses)))

    def matrices(n, contacts):
        M, K, p = random_structure(rng, n)
        return MultiScene.from_matrices(M, K, p, contacts, beta_ratio=ratio(len(contacts)))

    return [
        ("chain 2dof walls m1 m2", chain("ground", 2, [1, 2])),
        ("chain 3dof wall m1, m2-m3", chain(["ground", "mass"], 3, [1, 2])),
        ("chain 3dof base m1 m3", chain("base", 3, [1, 3])),
        ("random 2dof x0 x1", matrices(2, [("ground", 0), ("ground", 1)])),
        ("random 3dof x0, x1-x2", matrices(3, [("ground", 0), ("between", 1, 2)])),
        (
            "random 4dof x0, x1-x2, x3",
            matrices(4, [("ground", 0), ("between", 1, 2), ("ground", 3)]),
        ),
    ]


def draw_points(scene: MultiScene, index: int, count: int, seed: int = DRAW_SEED):
    """``(r, beta)`` of scene ``index`` of :func:`draw_scenes`: r = w1 U(0.1, 2.5)
    (w1 the lowest natural frequency of the structure without contacts), beta
    U(0.02, 1.2); one row per point, so the first points of any count coincide."""
    from scipy.linalg import eigh

    rng = np.random.default_rng([seed, index])
    w1 = math.sqrt(eigh(scene.stiffness_matrix(), scene.mass_matrix(1.0), eigvals_only=True)[0])
    u = rng.uniform(size=(count, 2))
    return w1 * (0.1 + 2.4 * u[:, 0]), 0.02 + 1.18 * u[:, 1]
