"""Sparse symmetric positive definite factorizations, factorized once and reused (precompute → solve).

Backends (``backend=``):
- ``cholespy``: CHOLMOD Cholesky (simplicial or supernodal, CHOLMOD's choice) through the `cholespy` wheel (no
  system SuiteSparse needed); solves many right-hand sides per call. The default for small heat-method systems.
- ``scipy``: SuperLU (``scipy.sparse.linalg.splu``) — always available, the fallback.
- ``pardiso``: Intel MKL PARDISO through `pypardiso` (installed with heatparam on x86-64; MKL has no other
  platforms): faster factorizations, a numerical refactorization that reuses the symbolic analysis
  (:meth:`Factor.refactor`), and, with MKL's iterative refinement switched off, solves as fast as CHOLMOD's.
  :func:`large_system_backend` picks it per use by measurement: the polish's Hessians at every size, the
  heat-method systems from 100k vertices, the conformal layouts from 20k unknowns. Large systems it orders
  itself get its improved two-level factorization, each factor's first solve checked
  (:data:`TWO_LEVEL_MIN_UNKNOWNS`).

``auto`` takes the first available of cholespy, scipy (then PARDISO per :func:`large_system_backend`).
"""

from __future__ import annotations

import contextlib
import functools
import importlib.util

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla


def available_backends() -> list[str]:
    """Backends importable here, in preference order."""
    out = []
    if importlib.util.find_spec("cholespy") is not None:
        out.append("cholespy")
    out.append("scipy")
    if importlib.util.find_spec("pypardiso") is not None:
        out.append("pardiso")
    return out


#: Default threshold of :func:`large_system_backend`: systems of at least this many unknowns use PARDISO when it is
#: installed and the backend is ``auto`` (a 196k-vertex cylinder patch's LSCM solve 1.7 s vs 10.0 s for igl.lscm;
#: BENCHMARKS.md §4). The uses measured apart pass their own (the heat method, the polish, the conformal layout).
PARDISO_MIN_UNKNOWNS = 200_000


def large_system_backend(unknowns: int, backend: str = "auto", min_unknowns: int = PARDISO_MIN_UNKNOWNS) -> str:
    """``backend`` unless ``auto``; then PARDISO for systems of ≥ ``min_unknowns`` unknowns when installed, else
    the default backend."""
    if backend != "auto":
        return backend
    avail = available_backends()
    return "pardiso" if unknowns >= min_unknowns and "pardiso" in avail else avail[0]


class Factor:
    """A factorization of an SPD matrix A (n,n); ``solve(b)`` accepts (n,) or (n,k) right-hand sides.

    upper : A is given as its upper triangle, sorted CSR (what PARDISO reads; only with the ``pardiso`` backend):
        it is used as it is, without a ``triu`` copy of a full matrix.
    ordering : PARDISO only: (fill-reducing permutation (n,), its factor's nonzeros) of an earlier analysis of a
        similar pattern, used instead of a new METIS ordering unless its factor has more than ``REORDER_FILL`` ×
        those nonzeros (:meth:`refactor`).
    numeric : False (PARDISO only): the symbolic analysis of A's pattern alone (its values are not read); the
        object cannot solve until :meth:`refactor` has factorized a matrix of that pattern (or one within it, which
        is then a numerical factorization only). A matrix of another pattern is analysed anew there as if this
        object had never been made. For an analysis made ahead of time, on another thread
        (``refine.newton.prepare_hessian``).
    """

    def __init__(self, A: sp.spmatrix, backend: str = "auto", upper: bool = False,
                 ordering: tuple[np.ndarray, int] | None = None, numeric: bool = True):
        if backend == "auto":
            backend = available_backends()[0]
        if backend not in available_backends():
            raise ValueError(f"solver backend {backend!r} is not installed (available: {available_backends()})")
        if (upper or not numeric) and backend != "pardiso":
            raise ValueError(f"an upper triangle or an analysis alone needs the pardiso backend, not {backend!r}")
        self.backend = backend
        self.symbolic = not numeric  # only analysed: nothing to solve with yet
        self.n = A.shape[0]
        self.ordering: tuple[np.ndarray, int] | None = None  # PARDISO's, for refactor() (set below)
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
            prepare_mkl()  # before the import: pypardiso makes a solver at import time
            import pypardiso

            self._T = A if upper else _upper(A)  # PARDISO reads the upper triangle of a symmetric matrix
            self._f = self._pardiso(pypardiso, ordering, numeric)
            if ordering is not None and self._f.iparm[17] > REORDER_FILL * ordering[1]:
                self._f.free_memory(everything=True)  # the old ordering fills in too much here: a new one
                self._f = self._pardiso(pypardiso, None, numeric)
            # the permutation and its fill, for refactor(); the fill of the METIS ordering it came from
            self.ordering = (self._f.perm, ordering[1] if ordering is not None and self._f.perm is ordering[0]
                             else int(self._f.iparm[17]))

    @property
    def _two_level_size(self) -> bool:
        """Large enough for PARDISO's two-level factorization where PARDISO orders the system itself
        (:data:`TWO_LEVEL_MIN_UNKNOWNS`; :meth:`refactor` then asks for a new ordering)."""
        return self.n >= TWO_LEVEL_MIN_UNKNOWNS

    def _pardiso(self, pypardiso, ordering: tuple[np.ndarray, int] | None, numeric: bool = True):
        """A PARDISO solver that has factorized ``self._T`` (``numeric`` False: analysed its pattern): with METIS's
        ordering, returned in its ``perm`` (iparm 5 = 2), or with ``ordering``'s permutation (iparm 5 = 1)."""
        f = pypardiso.PyPardisoSolver(mtype=2)  # real symmetric positive definite
        _remember_mkl(f)
        f.iparm[:] = _pardiso_defaults(pypardiso)
        # MKL's defaults add 2 steps of iterative refinement to every solve (3x the work: 0.53 vs 0.19 s for 16
        # columns on camelhead↑180k's heat matrix); a Cholesky of an SPD matrix needs none (residual 1e-15)
        f.iparm[7] = 0
        # METIS's OpenMP nested dissection: the same permutation as the serial one on every matrix measured, in
        # 1/3 less time on 2 cores
        f.iparm[1] = 3
        # the improved two-level factorization for large systems that PARDISO orders itself (TWO_LEVEL_MIN_UNKNOWNS)
        f.iparm[23] = 10 if ordering is None and self._two_level_size else 0
        if ordering is None:
            f.perm, f.iparm[4] = np.zeros(self.n, dtype=np.int32), 2
        else:
            f.perm, f.iparm[4] = ordering[0], 1
        try:
            with pardiso_threads(f, self.n):
                if numeric:
                    f.factorize(self._T)
                else:  # phase 11, as ``factorize`` calls phase 12 (the matrix checked, no copy of it kept)
                    f._check_A(self._T)
                    f.set_phase(11)
                    f._call_pardiso(self._T, np.zeros((self.n, 1)))
        except pypardiso.pardiso_wrapper.PyPardisoError as exc:  # e.g. -4, a zero pivot: NaN in the matrix
            f.free_memory(everything=True)
            raise np.linalg.LinAlgError(f"PARDISO could not factorize the matrix ({exc})") from None
        return f

    def refactor(self, A: sp.spmatrix, upper: bool = False) -> Factor:
        """A factorization of A (same size as this one's matrix; ``upper`` as for :class:`Factor`), reusing what
        can be reused.

        PARDISO keeps its symbolic analysis (the fill-reducing ordering: about half of a factorization's time) and
        refactorizes this object in place when A's sparsity pattern lies within the analysed one (A's values are
        placed on that pattern, explicit zeros elsewhere). Otherwise A's own pattern is analysed anew, with this
        factor's fill-reducing permutation: the polish's re-triangulated scaffold changes the pattern at nearly
        every iteration, but only in the scaffold's couplings, so the permutation still suits (camelhead↑180k's
        Hessian analysed in 0.50-0.67 s instead of 0.84-1.19 s with METIS, the same factor size). From
        ``TWO_LEVEL_MIN_UNKNOWNS`` unknowns the new pattern gets a new METIS ordering instead: only then is the
        factor two-level, whose refactorizations and solves pay for the ordering (at 624k unknowns
        refactorizations 0.44 vs 0.93 s, solves 0.08 vs 0.23 s).
        Other backends: a new :class:`Factor`. When PARDISO analyses anew, this object is freed first (:meth:`free`)
        and cannot solve any more.
        """
        if self.backend == "pardiso" and A.shape == self._T.shape:
            U = A if upper else _upper(A)
            same = (U.nnz == self._T.nnz and np.array_equal(U.indptr, self._T.indptr)
                    and np.array_equal(U.indices, self._T.indices))
            T = U if same else within(self._T, U)  # the same pattern (the polish kept its scaffold): as it is
            if T is not None and _pardiso_numeric(self._f, T):
                self._T, self.symbolic = T, False
                return self
            del T
            if self.symbolic:  # an analysis made ahead of time, of another pattern: as if it had never been made
                self.free()
                return Factor(U, self.backend, upper=True)
            # this factor is replaced: free MKL's copy of it before the new one is made, not after (factors of
            # ~0.5 GB at 624k unknowns: the peak RSS 2.3 → 1.9 GB)
            ordering = None if self._two_level_size else self.ordering
            self.free()
            return Factor(U, self.backend, upper=True, ordering=ordering)
        return Factor(A, self.backend, upper=upper)

    def free(self) -> None:
        """Release the factorization now (PARDISO keeps it in MKL's memory until told); the object cannot solve
        after this. :meth:`refactor` frees the factor it replaces."""
        if getattr(self, "backend", None) == "pardiso" and getattr(self, "_f", None) is not None:
            try:
                self._f.free_memory(everything=True)
            except Exception:  # noqa: BLE001 - interpreter shutdown: nothing left to free into
                pass
            self._f = self._T = None

    def rebuild_matrix(self) -> sp.spmatrix | None:
        """The matrix from which ``Factor(matrix, backend)`` makes this very factor again (PARDISO: the analysed
        pattern with the current values, explicit zeros included), or None where this object keeps no matrix (the
        caller keeps the one it factorized)."""
        return self._T if self.backend == "pardiso" else None

    def solve(self, b: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Solve A x = b for b (n,) or (n,k) float64; returns x, a new array of b's shape or ``out``.

        ``out``: optional C-contiguous float64 array of b's shape to write x into (the cholespy backend then
        solves straight into it, with no copy); it must not overlap b.
        """
        b = np.ascontiguousarray(b, dtype=np.float64)
        if self.backend == "cholespy":
            x = out if _writable_c_float64(out, b.shape) else np.empty_like(b)
            self._f.solve(b, x)
        elif self.backend == "scipy":
            x = self._f.solve(b)
        else:
            if self._f is None:
                raise RuntimeError("this PARDISO factorization was freed (Factor.free, or replaced by refactor)")
            if self.symbolic:
                raise RuntimeError("this PARDISO object holds an analysis only: refactor() a matrix first")
            with pardiso_threads(self._f, self.n):  # same matrix object: pypardiso reuses the factor
                x = self._f.solve(self._T, b).reshape(b.shape)
            # a two-level factor's first solve is checked (a bad factor solves every right-hand side badly)
            if self._f.iparm[23] == 10 and getattr(self, "_checked", None) is not self._T:
                if _solved(self._T, x, b, self._norm()):
                    self._checked = self._T  # this factor of this matrix solved well
                else:
                    # the two-level factorization solved badly: the classic one, with the same ordering, from now on
                    prepare_mkl()
                    import pypardiso

                    self._f.free_memory(everything=True)
                    self._f = self._pardiso(pypardiso, self.ordering)
                    with pardiso_threads(self._f, self.n):
                        x = self._f.solve(self._T, b).reshape(b.shape)
        if out is None:
            return x
        if x is not out:
            out[...] = x
        return out

    def _norm(self) -> float:
        """‖A‖∞ of the PARDISO matrix A (from its upper triangle), computed once per matrix."""
        if getattr(self, "_norm_of", None) is not self._T:
            aT = abs(self._T)
            self._norm_value = float(np.max(np.asarray(aT.sum(axis=1)).ravel() + np.asarray(aT.sum(axis=0)).ravel()
                                            - np.abs(self._T.diagonal())))
            self._norm_of = self._T
        return self._norm_value

    def __del__(self) -> None:
        # pypardiso keeps MKL's factor until told otherwise: without this every dropped Factor leaks it
        # (camelhead↑180k polish: 6.6 GB peak instead of 1.6 GB)
        self.free()


def solve_unsymmetric(A: sp.spmatrix, b: np.ndarray, backend: str = "auto") -> np.ndarray:
    """x with A x = b for a square non-symmetric A (n,n), b (n,) or (n,k), factorized once and freed: PARDISO's LU
    for systems of ≥ ``PARDISO_MIN_UNKNOWNS`` unknowns where it is installed (:func:`large_system_backend`), else
    SuperLU. (pypardiso's own ``spsolve`` keeps its factor, and a copy of A, until the next call: 200 MB at 201k
    unknowns.)"""
    b = np.ascontiguousarray(b, dtype=np.float64)
    if large_system_backend(A.shape[0], backend) != "pardiso":
        return spla.splu(sp.csc_matrix(A)).solve(b)
    prepare_mkl()
    import pypardiso

    f = pypardiso.PyPardisoSolver(mtype=11)  # real non-symmetric
    _remember_mkl(f)
    try:
        return f.solve(sp.csr_matrix(A), b).reshape(b.shape)
    finally:
        f.free_memory(everything=True)


#: A reused fill-reducing permutation is dropped for a new METIS ordering when its factor has more than this many
#: times the nonzeros of the factor the permutation was made for (:meth:`Factor.refactor`).
REORDER_FILL = 1.25

_DEFAULT_IPARM: np.ndarray | None = None


#: PARDISO's improved two-level factorization (iparm 24 = 10, 1-based; 0, the classic one, is MKL's default) for
#: systems of at least this many unknowns that PARDISO orders itself (iparm 5 = 2): faster factorizations and 3-4×
#: faster solves, the same maps to 11-13 digits (BENCHMARKS.md §23f). Not below this size (an atlas's charts of
#: tens of faces came out worse), nor with a permutation given (iparm 5 = 1: not reproducible run to run, and
#: wrong). The first solve of every such factor is checked (:data:`TWO_LEVEL_BACKWARD_ERROR`).
TWO_LEVEL_MIN_UNKNOWNS = 100_000


#: A two-level factor's first solve is checked: its normwise backward error ‖A x − b‖∞ / (‖A‖∞ ‖x‖∞ + ‖b‖∞)
#: (per column) must stay below this. A stable Cholesky solve's is ~1e-16 whatever the conditioning (the spectral
#: conformal layout solves with a nearly singular matrix on purpose), the bad solves measured orders of magnitude
#: more.
TWO_LEVEL_BACKWARD_ERROR = 1e-10


def _solved(T: sp.csr_matrix, x: np.ndarray, b: np.ndarray, norm: float) -> bool:
    """Whether x solves A x = b to ``TWO_LEVEL_BACKWARD_ERROR`` (per column), A given by its upper triangle T, norm
    its ‖A‖∞."""
    r = T @ x + T.T @ x - T.diagonal().reshape(-1, *([1] * (x.ndim - 1))) * x - b
    scale = norm * np.max(np.abs(x), axis=0) + np.max(np.abs(b), axis=0)
    return bool(np.all(np.max(np.abs(r), axis=0) <= TWO_LEVEL_BACKWARD_ERROR * np.maximum(scale, 1e-300)))


def _pardiso_defaults(pypardiso) -> np.ndarray:
    """PARDISO's default iparm for a real SPD matrix (64,) int32, with iparm 1 = 1 (explicit values): what PARDISO
    fills in on a first call with iparm 1 = 0, read once from an analysis of a 2×2 identity. Explicit values are
    needed to ask for (iparm 5 = 2) or give (iparm 5 = 1) the fill-reducing permutation."""
    global _DEFAULT_IPARM
    if _DEFAULT_IPARM is None:
        probe = pypardiso.PyPardisoSolver(mtype=2)
        _remember_mkl(probe)
        probe.set_phase(11)
        probe._call_pardiso(sp.identity(2, format="csr"), np.zeros(2))
        iparm = probe.iparm.copy()
        probe.free_memory(everything=True)
        iparm[17] = -1  # report the factor's nonzeros (iparm 18) at every analysis
        _DEFAULT_IPARM = iparm
    return _DEFAULT_IPARM


def _upper(A: sp.spmatrix) -> sp.csr_matrix:
    T = sp.triu(A, format="csr")
    T.sort_indices()
    return T


def _csr_keys(M: sp.csr_matrix) -> np.ndarray:
    """(nnz,) int64 row-major keys row × ncols + column of a sorted CSR matrix's entries (ascending)."""
    return np.repeat(np.arange(M.shape[0], dtype=np.int64), np.diff(M.indptr)) * M.shape[1] + M.indices


def within(P: sp.csr_matrix, T: sp.csr_matrix) -> sp.csr_matrix | None:
    """T's values on P's sparsity pattern (explicit zeros where only P has entries) when T's pattern lies within
    P's, else None (sorted CSR, same shape). No union is formed: a T with more entries than P, in all or in a row,
    is not within it, and otherwise T's entries are looked up among P's (a union, built only to be compared with
    P, cost 0.43 s per iteration at 311k vertices)."""
    if T.nnz > P.nnz or (np.diff(T.indptr) > np.diff(P.indptr)).any():  # a row with more entries: not within
        return None
    kp, kt = _csr_keys(P), _csr_keys(T)
    pos = np.searchsorted(kp, kt)
    if len(kt) and (pos[-1] >= len(kp) or not np.array_equal(kp[np.minimum(pos, len(kp) - 1)], kt)):
        return None
    data = np.zeros(P.nnz)
    data[pos] = T.data
    return sp.csr_matrix((data, P.indices, P.indptr), shape=P.shape)


def _pardiso_numeric(solver, T: sp.csr_matrix) -> bool:
    """PARDISO phase 22 (numerical factorization only) of T, whose pattern was analysed before; what
    ``PyPardisoSolver.factorize`` does with phase 12. False if this pypardiso lacks the internals used."""
    try:
        solver._check_A(T)
        stored = solver._hash_csr_matrix(T) if T.nnz > solver.size_limit_storage else T
        solver.set_phase(22)
        with pardiso_threads(solver, T.shape[0]):
            solver._call_pardiso(T, np.zeros((T.shape[0], 1)))
    except AttributeError:
        return False
    solver.factorized_A = stored  # what solve() compares its matrix with
    return True


#: PARDISO runs on one thread for SPD systems of fewer unknowns than this (the thread that calls it only:
#: :func:`pardiso_threads`); larger ones on all of MKL's threads. Small factorizations gain little from a second
#: thread and lose much when the machine is busy (cow's atlas, 12k unknowns: 0.508 vs 0.368 s beside a process
#: that kept one core busy, the same time when quiet; BENCHMARKS.md §26). Every classic factorization is below it
#: (``TWO_LEVEL_MIN_UNKNOWNS``), so the polish's coarse levels run serial: at 22k / 44k unknowns on the shared 2-core
#: machine 2× / 1.4× faster, the same bits (MKL_CBWR); the two-level factorizations above gained nothing serial.
PARDISO_SERIAL_BELOW = TWO_LEVEL_MIN_UNKNOWNS


@contextlib.contextmanager
def pardiso_threads(solver, n: int):
    """Within this block MKL uses one thread on the calling thread when the system has fewer than
    ``PARDISO_SERIAL_BELOW`` unknowns (``mkl_set_num_threads_local``; the setting before is restored after it);
    otherwise, or where this MKL lacks the call, nothing changes. A factor keeps one thread count from its analysis
    to its solves, as MKL's reproducibility (``MKL_CBWR``) asks: the count depends on n alone."""
    fn = _local_threads(solver) if n < PARDISO_SERIAL_BELOW else None
    if fn is None:
        yield
        return
    before = fn(1)
    try:
        yield
    finally:
        fn(before)


def _local_threads(solver):
    """MKL's ``MKL_Set_Num_Threads_Local`` (int → the previous local setting, 0: none) from the library pypardiso
    loaded, or None."""
    return _set_threads_local(getattr(solver, "libmkl", None))


@functools.cache
def _set_threads_local(lib):
    import ctypes

    fn = getattr(lib, "MKL_Set_Num_Threads_Local", None)
    if fn is not None:
        fn.restype, fn.argtypes = ctypes.c_int, [ctypes.c_int]
    return fn


def prepare_mkl() -> None:
    """Before MKL is loaded: ask for reproducible results, and name libmkl_rt for pypardiso.

    - ``MKL_CBWR=AUTO`` (unless set): MKL's conditional numerical reproducibility. Without it PARDISO's threaded
      factorization sums in a varying order and the same input gave a different map in every run (camelhead: three
      runs, three results); with it the runs are bit-identical, at ~5-10% of the polish's time (camelhead↑45k).
    - ``PYPARDISO_MKL_RT``: where the `mkl` wheel puts the library (the environment's lib folder); otherwise
      pypardiso's first solver searches all of sys.prefix recursively for it (0.7 s here).
    """
    import glob
    import os
    import sys

    os.environ.setdefault("MKL_CBWR", "AUTO")
    if "PYPARDISO_MKL_RT" in os.environ:
        return
    found = sorted(glob.glob(os.path.join(sys.prefix, "lib", "libmkl_rt.so*")), key=len)
    if found:
        os.environ["PYPARDISO_MKL_RT"] = found[0]


def _remember_mkl(solver) -> None:
    """pypardiso searches sys.prefix for libmkl_rt at every solver it creates (0.3 s here) unless
    PYPARDISO_MKL_RT names it: name the library the first solver found."""
    import os

    path = getattr(getattr(solver, "libmkl", None), "_name", None)
    if path:
        os.environ.setdefault("PYPARDISO_MKL_RT", path)


def _writable_c_float64(a: np.ndarray | None, shape: tuple[int, ...]) -> bool:
    return (a is not None and a.shape == shape and a.dtype == np.float64 and a.flags.c_contiguous
            and a.flags.writeable)
