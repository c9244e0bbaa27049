"""Sparse symmetric positive definite factorizations, factorized once and reused (precompute → solve).

Backends (``backend=``):
- ``cholespy``: CHOLMOD supernodal Cholesky through the `cholespy` wheel (no system SuiteSparse needed);
  solves many right-hand sides per call. The default when installed.
- ``scipy``: SuperLU (``scipy.sparse.linalg.splu``) — always available, the fallback.
- ``pardiso``: Intel MKL PARDISO through `pypardiso`, if installed (x86-64 only).

``auto`` takes the first available of cholespy, scipy; BENCHMARKS.md has the measurements behind it.
"""

from __future__ import annotations

import importlib.util

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

BACKENDS = ("auto", "cholespy", "scipy", "pardiso")


def available_backends() -> list[str]:
    """Backends importable here, in preference order."""
    out = []
    if importlib.util.find_spec("cholespy") is not None:
        out.append("cholespy")
    out.append("scipy")
    if importlib.util.find_spec("pypardiso") is not None:
        out.append("pardiso")
    return out


class Factor:
    """A factorization of an SPD matrix A (n,n); ``solve(b)`` accepts (n,) or (n,k) right-hand sides."""

    def __init__(self, A: sp.spmatrix, backend: str = "auto"):
        if backend == "auto":
            backend = available_backends()[0]
        if backend not in available_backends():
            raise ValueError(f"solver backend {backend!r} is not installed (available: {available_backends()})")
        self.backend = backend
        self.n = A.shape[0]
        if backend == "cholespy":
            import cholespy

            A = sp.csc_matrix(A)
            A.sort_indices()
            self._f = cholespy.CholeskySolverD(
                self.n, A.indptr.astype(np.int32), A.indices.astype(np.int32), A.data.astype(np.float64),
                cholespy.MatrixType.CSC,
            )
        elif backend == "scipy":
            self._f = spla.splu(sp.csc_matrix(A), permc_spec="MMD_AT_PLUS_A", options={"SymmetricMode": True})
        else:
            import pypardiso

            self._A = sp.csr_matrix(A)
            self._f = pypardiso.PyPardisoSolver(mtype=2)  # real symmetric positive definite
            self._f.factorize(sp.triu(self._A, format="csr"))

    def solve(self, b: np.ndarray) -> np.ndarray:
        """Solve A x = b for b (n,) or (n,k) float64; returns a new array of b's shape."""
        b = np.ascontiguousarray(b, dtype=np.float64)
        if self.backend == "cholespy":
            x = np.empty_like(b)
            self._f.solve(b, x)
            return x
        if self.backend == "scipy":
            return self._f.solve(b)
        return self._f.solve(sp.triu(self._A, format="csr"), b).reshape(b.shape)
