"""Small dense linear systems of the kernel, solved without LAPACK.

The kernel solves systems of dimension ``2 N`` at most (the stiffness matrix for
the static response and the compliance of the contact, Newton steps of
shooting) once or a few times per point. LAPACK's ``gesv`` through numba copies
its operands, allocates its workspace and wakes the threads of the BLAS library,
which then spin for a while: more than the elimination itself costs at these
sizes. Gaussian elimination with partial pivoting (the algorithm of ``gesv``)
gives the same solution to rounding.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def _solve(A, rhs):
    """``x`` with ``A x = rhs``: Gaussian elimination with partial pivoting. All NaN
    where a pivot is 0 (``A`` singular: e.g. no isolated fixed point in shooting)."""
    dim = A.shape[0]
    M = A.copy()
    x = rhs.copy()
    for k in range(dim):
        p = k
        big = abs(M[k, k])
        for i in range(k + 1, dim):
            if abs(M[i, k]) > big:
                big = abs(M[i, k])
                p = i
        if not big > 0.0:
            x[:] = np.nan
            return x
        if p != k:
            for j in range(dim):
                M[k, j], M[p, j] = M[p, j], M[k, j]
            x[k], x[p] = x[p], x[k]
        for i in range(k + 1, dim):
            f = M[i, k] / M[k, k]
            for j in range(k + 1, dim):
                M[i, j] -= f * M[k, j]
            x[i] -= f * x[k]
    for k in range(dim - 1, -1, -1):
        acc = x[k]
        for j in range(k + 1, dim):
            acc -= M[k, j] * x[j]
        x[k] = acc / M[k, k]
    return x
