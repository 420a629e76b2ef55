"""A beam with two contact points (tasks.structures.beam, docs/contacts.md) against
independent truths:

* a contact that never slides (beta_ratio 1e5) equals the beam held at that node:
  the node's row and column removed *before* the Craig-Bampton reduction, built
  here from :func:`tasks.structures.beam_model` (for a reduced beam this is exactly
  the reduced model with that DOF held: the same constraint and fixed-interface
  modes), classified by the single-contact kernel;
* a contact with beta_ratio 0 equals the beam with one contact
  (``beam(contact_node=j)``, the one-contact path of the beam API);
* the energy balance per period: the load's work equals the contacts'
  dissipation. The work is integrated exactly over every recorded phase (Van
  Loan's block matrix exponential of the reference's state-space operator: the
  beam's fast modes would need many Gauss nodes per phase).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import eigh, expm
from test_multicontact import _assert_same

from tasks import Scene, classify, regimes
from tasks.classifier import settings_args
from tasks.fidelity import resolve
from tasks.multicontact import MultiScene, steady
from tasks.multicontact import reference as ref
from tasks.multicontact.classify import stuck_sets_cached
from tasks.structures import beam, beam_model, craig_bampton

N_ELEMENTS, NODES, MODES = 10, [5, 10], 3
#: The single-contact kernel's orbit as accurate as the comparison (its section_rtol).
TIGHT = {"section_rtol": 1e-13, "design": True}  # force and dissipation compared


def held_beam(node_held: int, node_contact: int, modes: int, load: str) -> Scene:
    """The cantilever of ``N_ELEMENTS`` elements held at ``node_held`` (row and column
    removed before any reduction) with one contact at ``node_contact``, K scaled by
    the first eigenvalue of the beam without any contact (as tasks.structures.beam)."""
    model = beam_model(N_ELEMENTS)
    lam1 = eigh(model.stiffness, model.mass, eigvals_only=True, subset_by_index=[0, 0])[0]
    keep = [i for i in range(model.dofs.size) if i != model.index(node_held)]
    M = model.mass[np.ix_(keep, keep)]
    K = model.stiffness[np.ix_(keep, keep)] / lam1
    p = model.load_vector(load)[keep]
    j = keep.index(model.index(node_contact))
    V = craig_bampton(M, K, [j], modes)
    return Scene.from_matrices(V.T @ M @ V, V.T @ K @ V, V.T @ p, ("ground", 0))


def grid(n_r: int = 6, n_beta: int = 4) -> tuple[np.ndarray, np.ndarray]:
    r, beta = np.meshgrid(np.linspace(0.3, 2.8, n_r), np.linspace(0.1, 1.6, n_beta))
    return r.ravel(), beta.ravel()


def test_the_beam_scene_has_a_contact_at_each_node():
    scene = beam(N_ELEMENTS, contact_node=NODES, modes=MODES, beta_ratio=[1.0, 0.5])
    assert isinstance(scene, MultiScene) and scene.contacts == (("ground", 0), ("ground", 1))
    assert scene.dof == 2 + MODES and scene.beta_ratio == (1.0, 0.5)
    # the boundary DOFs stay physical: a static load at the tip deflects DOF 1 as the full beam
    full = beam(N_ELEMENTS, contact_node=NODES, beta_ratio=[1.0, 0.5])
    tip = full.contacts[1][1]
    static_full = np.linalg.solve(full.stiffness_matrix(), full.load_vector())
    static_red = np.linalg.solve(scene.stiffness_matrix(), scene.load_vector())
    assert static_red[1] == pytest.approx(static_full[tip], rel=1e-12)
    for bad, field in (([5, 5], "contact_node"), ([5], "contact_node"), ([0, 5], "contact_node")):
        with pytest.raises(ValueError, match=f"^{field}: "):
            beam(N_ELEMENTS, contact_node=bad)
    with pytest.raises(ValueError, match="^beta_ratio: "):
        beam(N_ELEMENTS, contact_node=5, beta_ratio=[1.0])


@pytest.mark.parametrize(("stuck", "free"), [(0, 1), (1, 0)])
def test_a_contact_that_never_slides_is_the_beam_held_at_that_node(stuck, free):
    ratio = [1.0, 1.0]
    ratio[stuck] = 1e5
    load = "distributed"  # a tip force on a held tip would move nothing
    multi = beam(N_ELEMENTS, contact_node=NODES, load=load, modes=MODES, beta_ratio=ratio)
    r, beta = grid()
    res = classify(multi, r, beta, fidelity="exact")
    held = held_beam(NODES[stuck], NODES[free], MODES, load)
    _assert_same(res, free, classify(held, r, beta, fidelity="exact", **TIGHT))
    assert np.all(res.regime[res.converged, stuck] == regimes.NO_MOTION)
    assert len(np.unique(res.regime[res.converged, free])) >= 2  # not a trivial map


def test_a_contact_without_friction_is_the_beam_with_one_contact():
    r, beta = grid()
    multi = beam(3, contact_node=[2, 3], beta_ratio=[1.0, 0.0])  # full model: same matrices
    res = classify(multi, r, beta, fidelity="exact")
    single = classify(beam(3, contact_node=2), r, beta, fidelity="exact", **TIGHT)
    _assert_same(res, 0, single)
    assert len(np.unique(single.regime)) >= 2
    assert np.all(res.regime[res.converged, 1] == regimes.CONTINUOUS)


def work_and_dissipation(scene: MultiScene, r: float, beta: float) -> tuple[float, float]:
    """The load's work per excitation cycle over the recorded steady period, exact per
    phase: with ``z = (x, x', cos tau, sin tau, 1)`` and ``z' = A z`` (the reference's
    operator of the phase's stuck set), the work ``int cos(tau) p . x' dtau`` is
    ``z0^T (int_0^T e^(A^T t) Q e^(A t) dt) z0``, the integral from one matrix
    exponential (Van Loan 1978); and the simulator's dissipation."""
    args = stuck_sets_cached(scene).kernel_args()
    og, oc, rec, rows = steady.record_orbit(r, beta, args, settings_args(resolve("exact")), 400)
    assert og[0] == 1.0 and rows < 400
    sys = ref._System(scene, r, beta)
    n, k, m = sys.n, sys.k, 2 * sys.n + 3
    Q = np.zeros((m, m))
    Q[2 * n, n : 2 * n] = Q[n : 2 * n, 2 * n] = 0.5 * sys.p
    work = 0.0
    for i in range(rows - 1):
        tau0, tau1 = rec[i, 0], rec[i + 1, 0]
        if tau1 <= tau0:
            continue  # the end of one cycle and the start of the next
        stuck = tuple(c for c in range(k) if int(rec[i, 1]) >> c & 1)
        A = ref._operator(sys, stuck, {c: rec[i, 2 + c] for c in range(k)})[0]
        z0 = np.concatenate([rec[i, 2 + k :], [np.cos(tau0), np.sin(tau0), 1.0]])
        F = expm(np.block([[-A.T, Q], [np.zeros((m, m)), A]]) * (tau1 - tau0))
        work += z0 @ (F[m:, m:].T @ F[:m, m:]) @ z0
    return work / og[2], oc[:, 4].sum()


def test_energy_balance_per_period_on_the_beam():
    scene = beam(N_ELEMENTS, contact_node=NODES, modes=MODES, beta_ratio=[1.0, 0.5])
    checked = 0
    for r, beta in ((0.6, 0.4), (1.1, 0.8), (1.9, 1.2), (2.6, 0.3)):
        work, dissipation = work_and_dissipation(scene, r, beta)
        checked += dissipation > 0.0
        assert abs(work - dissipation) <= 1e-9 * max(dissipation, 1.0), (r, beta)
    assert checked >= 3
