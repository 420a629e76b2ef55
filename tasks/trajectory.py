"""Event-by-event trajectories: what happened at every event, and the state at any time.

:func:`classify` answers "which regime?"; :func:`trajectory` shows the motion
behind the answer: the times and kinds of every event (stop, reversal,
unstick), the state there, and (:meth:`Trajectory.sample`) the exact state at
any time, from the same closed-form phases the classifier uses.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from tasks import kernel, numba_cache
from tasks.classifier import (
    base_influence,
    result_from_kernel,
    scene_modes_cached,
    settings_args,
)
from tasks.fidelity import resolve
from tasks.result import ClassifyResult
from tasks.scene import Scene

#: Names of the event kinds in :attr:`Trajectory.kind`.
EVENT_KINDS: dict[int, str] = {
    int(kernel.EV_SECTION): "section",
    int(kernel.EV_STOP): "stop",
    int(kernel.EV_REVERSAL): "reversal",
    int(kernel.EV_UNSTICK): "unstick",
    int(kernel.EV_GRAZE): "graze",
    int(kernel.EV_END): "end",
}


@dataclass
class Trajectory:
    """Events of a simulated stretch of motion (scene coordinates, docs/theory.md 2).

    Attributes
    ----------
    tau : ndarray
        Event times (absolute: the excitation is ``cos(tau)``; one cycle is
        ``2 pi``). The first row of every cycle is its start (``"section"``,
        at ``tau = 0`` or at the phase of the Poincare section the classifier
        used), the last its end.
    kind : ndarray of int
        Event kinds, names in :data:`EVENT_KINDS`.
    mode : ndarray of int
        Phase after the event: +1 / -1 sliding with that sign of ``b . x'``, 0 stuck.
    g : ndarray
        Force the contact must transmit at the event (``|g| <= beta`` sticks).
    x, xd : ndarray, shape (n_events, N)
        State at the event (before any projection onto the stuck phase).
    status : int
        0, or the undetermined code of :mod:`tasks.regimes` that stopped the run.
    result : ClassifyResult or None
        The classification, when the trajectory starts from the steady state.
    """

    scene: Scene
    r: float
    beta: float
    tau: np.ndarray
    kind: np.ndarray
    mode: np.ndarray
    g: np.ndarray
    x: np.ndarray
    xd: np.ndarray
    status: int
    result: ClassifyResult | None
    _records: np.ndarray
    _ctx: tuple
    _work: tuple

    @property
    def contact_displacement(self) -> np.ndarray:
        """``b . x`` at every event (relative displacement of the contact)."""
        return self.x @ self.scene.contact_vector()

    @property
    def contact_velocity(self) -> np.ndarray:
        """``b . x'`` at every event."""
        return self.xd @ self.scene.contact_vector()

    def kinds(self, name: str) -> np.ndarray:
        """Boolean mask of the events of one kind, e.g. ``kinds("stop")``."""
        code = {v: k for k, v in EVENT_KINDS.items()}[name]
        return self.kind == code

    @property
    def periodic(self) -> bool:
        """The stretch is one converged steady-state period (``start="steady"``)."""
        return bool(
            self.result is not None
            and bool(self.result.converged)
            and self.status == 0
            and np.isclose(self.tau[-1] - self.tau[0], 2 * np.pi * int(self.result.period))
        )

    def sample(self, tau: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Exact state ``(x, x')`` at times ``tau`` (closed form).

        A steady-state trajectory (:attr:`periodic`) is the periodic orbit, so
        any time is mapped into its period (``sample(0.0)`` is the state at
        ``tau = 0`` although the recorded period may start at the section
        phase); any other trajectory is sampled within its stretch only.

        Returns
        -------
        x, xd : ndarray, shape ``(*np.shape(tau), N)``
        """
        tau = np.asarray(tau, dtype=float)
        start, end = float(self.tau[0]), float(self.tau[-1])
        if self.periodic:  # times outside the recorded period: the same phase inside it
            inside = (tau >= start) & (tau <= end)
            tau = np.where(inside, tau, start + np.mod(tau - start, end - start))
        order = np.argsort(tau.ravel())
        flat = np.ascontiguousarray(tau.ravel()[order])
        if flat.size and (flat[0] < start or flat[-1] > end):
            raise ValueError(
                f"tau: outside the simulated stretch [{start:.6g}, {end:.6g}] "
                "(only a converged steady state is periodic)"
            )
        states = kernel.sample_states(self._ctx, self._work, self._records, flat)
        back = np.empty_like(states)
        back[order] = states
        n = self.scene.dof
        shape = (*tau.shape, n)
        return back[:, :n].reshape(shape), back[:, n:].reshape(shape)


def trajectory(
    scene: Scene,
    r: float,
    beta: float,
    cycles: int | None = None,
    start: str | tuple[np.ndarray, np.ndarray] = "steady",
    fidelity: str = "balanced",
    max_records: int = 100_000,
    **settings: object,
) -> Trajectory:
    """Simulate ``cycles`` excitation periods of one point and record every event.

    Parameters
    ----------
    scene, r, beta
        As in :func:`tasks.classify` (scalars).
    cycles : int, optional
        Periods to record; default: the steady-state period (1 or 2) for
        ``start="steady"``, else 1.
    start : "steady", "held" or (x, x')
        ``"steady"``: classify the point first and record from its converged
        section state; ``"held"``: the classifier's initial condition;
        ``(x, x')``: any state at ``tau = 0`` (the phase follows from ``b . x'``
        and, at zero contact velocity, from ``|g| <= beta``).
    """
    resolved = resolve(fidelity, **settings)
    args = settings_args(resolved)
    scene_args = scene_modes_cached(scene).kernel_args()
    r = float(r)
    beta = float(beta)
    n = scene.dof
    result = None
    theta = 0.0
    numba_cache.announce_compile()  # one line on stderr before a first compile
    ctx, work = kernel._context(r, beta, scene_args, args)[:2]
    if isinstance(start, str) and start == "steady":
        rb = (np.array([r]), np.array([beta]))
        out, final = kernel.run_points(*rb, scene_args, args)
        design, _ = kernel.orbit_designs(*rb, scene_args, args, out, final, kernel.DESIGN_SAMPLES)
        result = result_from_kernel(out, (), design, base_influence(scene), codes=[args[9]])
        X0 = final[0, : 2 * n].copy()
        mode0 = int(final[0, 2 * n])
        theta = float(final[0, 2 * n + 1])
        if cycles is None:
            cycles = max(1, int(result.period))
    elif isinstance(start, str) and start == "held":
        X0, mode0 = np.zeros(2 * n), -9
    elif isinstance(start, str):
        raise ValueError(f"start: must be 'steady', 'held' or (x, xd), got {start!r}")
    else:
        x0, xd0 = (np.asarray(v, dtype=float).reshape(n) for v in start)
        X0 = np.concatenate([x0, xd0])
        mode0 = int(kernel.start_phase(X0, beta, ctx, 0.0))
    cycles = 1 if cycles is None else int(cycles)
    rec, n_rec, _, _, status = kernel.trace_cycles(
        r, beta, scene_args, args, X0, mode0, theta, cycles, max_records
    )
    rec = rec[:n_rec].copy()
    x = rec[:, kernel.REC_X : kernel.REC_X + n]
    return Trajectory(
        scene=scene,
        r=r,
        beta=beta,
        tau=rec[:, kernel.REC_TAU].copy(),
        kind=rec[:, kernel.REC_KIND].astype(int),
        mode=rec[:, kernel.REC_MODE].astype(int),
        g=rec[:, kernel.REC_G].copy(),
        x=x.copy(),
        xd=rec[:, kernel.REC_X + n :].copy(),
        status=int(status),
        result=result,
        _records=np.ascontiguousarray(rec),
        _ctx=ctx,
        _work=work,
    )
