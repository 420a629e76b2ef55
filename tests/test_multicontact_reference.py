"""Several contacts against the independent scipy reference (tasks.multicontact.reference),
and the numba cache key of the several-contact simulator.

The reference shares nothing with the compiled simulator but the scene: full
coordinates, contact forces as Lagrange multipliers, matrix-exponential
propagation, brentq events, the decision rule of docs/contacts.md 3 rewritten in
numpy. Unseen scenes, random points; compared where both reached a steady state.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from tasks import numba_cache
from tasks.multicontact import MultiScene, classify_multi
from tasks.multicontact.reference import reference_regimes

sys.path.insert(0, str(Path(__file__).parent))
from test_multicontact import points, random_structure  # noqa: E402

#: The target of the issue (measured: every compared per-contact regime agrees).
MIN_AGREEMENT = 0.99


def test_per_contact_regimes_agree_with_the_reference():
    M, K, p = random_structure(202, 2)
    scenes = [
        (
            MultiScene.chain("ground", 2, [1, 2], gamma=0.7, kappa=1.6, beta_ratio=[1.0, 0.5]),
            np.diag([1.0, 0.7]),
            np.array([[2.6, -1.6], [-1.6, 1.6]]),
        ),
        (
            MultiScene.from_matrices(
                M, K, p, [("ground", 0), ("ground", 1)], beta_ratio=[0.7, 1.0]
            ),
            M,
            K,
        ),
    ]
    compared = agreed = 0
    for scene, Ms, Ks in scenes:
        r, beta = points(8, 15, Ks, Ms)
        res = classify_multi(scene, r, beta)
        assert res.converged.mean() >= 0.9
        for i in range(r.size):
            ref, ok = reference_regimes(scene, r[i], beta[i], max_cycles=600)
            if ok and res.converged[i]:
                compared += 2
                agreed += int((ref == res.regime[i]).sum())
    assert compared >= 40
    assert agreed / compared >= MIN_AGREEMENT


def test_the_cache_key_covers_the_multicontact_and_kernel_sources(tmp_path):
    import shutil

    root = tmp_path / "tasks"
    repo = Path(__file__).resolve().parents[1] / "tasks"
    shutil.copytree(repo, root, ignore=shutil.ignore_patterns("__pycache__"))
    sources = numba_cache.MULTICONTACT_SOURCES
    key = numba_cache.kernel_key(root, sources)
    assert key == numba_cache.kernel_key(repo, sources)
    assert key != numba_cache.kernel_key(root)  # not the kernel's own folder
    for name in (
        "kernel/propagation.py",
        "kernel/events.py",
        "multicontact/cycle.py",
        "regimes.py",
    ):
        path = root / name
        text = path.read_text()
        path.write_text(text + "\n")
        assert numba_cache.kernel_key(root, sources) != key, name
        path.write_text(text)
    (root / "scene.py").write_text((root / "scene.py").read_text() + "\n")
    assert numba_cache.kernel_key(root, sources) == key
    folder = numba_cache.kernel_cache_folder(root, sources, "multicontact")
    assert folder.name == f"multicontact-{key}"
