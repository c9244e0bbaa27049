"""Sparse SPD factorizations: backends and refactorization with a reused analysis (``solvers``)."""

import contextlib

import numpy as np
import pytest
import scipy.sparse as sp

from heatparam import solvers
from heatparam.solvers import Factor, available_backends


def _spd(n: int = 400, seed: int = 0) -> sp.csc_matrix:
    """A random SPD matrix: a path-graph Laplacian plus random extra edges, plus the identity."""
    rng = np.random.default_rng(seed)
    i = np.concatenate([np.arange(n - 1), rng.integers(0, n, 3 * n)])
    j = np.concatenate([np.arange(1, n), rng.integers(0, n, 3 * n)])
    keep = i != j
    W = sp.coo_matrix((rng.uniform(0.5, 2.0, keep.sum()), (i[keep], j[keep])), shape=(n, n)).tocsr()
    W = W + W.T
    return (sp.diags(np.asarray(W.sum(axis=1)).ravel() + 1.0) - W).tocsc()


def _drop_pair(A: sp.spmatrix, r: int, c: int) -> sp.csc_matrix:
    """A with the symmetric pair (r,c), (c,r) removed from its pattern (diagonal made dominant again)."""
    A = sp.lil_matrix(A)
    A[r, r] += abs(A[r, c])
    A[c, c] += abs(A[r, c])
    A[r, c] = A[c, r] = 0.0
    A = sp.csc_matrix(A)
    A.eliminate_zeros()
    return A


def test_within_places_values_on_the_old_pattern_or_refuses():
    P = sp.csr_matrix(np.array([[1.0, 2.0, 0.0], [0.0, 3.0, 4.0], [0.0, 0.0, 5.0]]))
    T = sp.csr_matrix(np.array([[7.0, 0.0, 0.0], [0.0, 9.0, 0.0], [0.0, 0.0, 6.0]]))  # within P's pattern
    U = solvers.within(P, T)
    assert U.nnz == P.nnz and np.array_equal(U.indices, P.indices) and np.array_equal(U.indptr, P.indptr)
    assert np.array_equal(U.toarray(), T.toarray())  # T's values; explicit zeros at (0,1) and (1,2)
    assert solvers.within(P, P).nnz == P.nnz
    T2 = sp.csr_matrix(np.array([[7.0, 0.0, 8.0], [0.0, 9.0, 0.0], [0.0, 0.0, 6.0]]))  # (0,2): not in P
    assert T2.nnz <= P.nnz and solvers.within(P, T2) is None
    T3 = sp.csr_matrix(np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 9.0]]))  # P's last entry alone
    assert np.array_equal(solvers.within(P, T3).toarray(), T3.toarray())
    T4 = sp.csr_matrix(np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]))  # (2,0): not in P
    assert solvers.within(P, T4) is None
    assert solvers.within(P, sp.csr_matrix(np.ones((3, 3)))) is None  # more entries than P


@pytest.mark.skipif("pardiso" not in available_backends(), reason="pypardiso not installed")
def test_pardiso_refactor_reuses_the_analysis_while_the_pattern_fits():
    rng = np.random.default_rng(1)
    A = _spd()
    b = rng.standard_normal(A.shape[0])
    f = Factor(A, "pardiso")
    A2 = A + sp.diags(rng.uniform(0.0, 1.0, A.shape[0]))  # same pattern, new values
    f2 = f.refactor(A2)
    assert f2 is f and np.allclose(A2 @ f2.solve(b), b, atol=1e-9)
    r, c = A.indices[A.indptr[5]], 5  # an entry of column 5 ...
    r = r if r != c else A.indices[A.indptr[5] + 1]  # ... off the diagonal
    A3 = _drop_pair(A2, r, c)  # a smaller pattern: still within the analysed one
    assert A3.nnz < A2.nnz
    f3 = f2.refactor(A3)
    assert f3 is f and np.allclose(A3 @ f3.solve(b), b, atol=1e-9)
    A4 = A3 + sp.coo_matrix(([-0.1, -0.1, 0.2, 0.2], ([0, 399, 0, 399], [399, 0, 0, 399])), shape=A.shape)
    f4 = f3.refactor(A4)  # (0,399) is new: A4's own pattern analysed again
    assert f4 is not f and np.allclose(A4 @ f4.solve(b), b, atol=1e-9)
    assert f4.refactor(A3) is f4  # A3's pattern lies within A4's
    assert np.allclose(A3 @ f4.solve(b), b, atol=1e-9)


def _grid_laplacian(k: int) -> sp.csc_matrix:
    """The SPD 5-point Laplacian (+ identity) of a k×k grid, rows numbered row by row."""
    L1 = sp.diags([-np.ones(k - 1), 2.0 * np.ones(k), -np.ones(k - 1)], [-1, 0, 1])
    return (sp.kronsum(L1, L1) + sp.identity(k * k)).tocsc()


@pytest.mark.skipif("pardiso" not in available_backends(), reason="pypardiso not installed")
def test_pardiso_new_analysis_reuses_the_ordering_unless_it_fills_in_too_much():
    rng = np.random.default_rng(3)
    A = _grid_laplacian(40)
    n = A.shape[0]
    b = rng.standard_normal(n)
    f = Factor(A, "pardiso")
    perm, fill = f.ordering
    assert sorted(perm.tolist()) == list(range(1, n + 1)) and fill > n  # METIS's permutation (1-based), its fill
    near = sp.coo_matrix(([-0.1, -0.1, 0.2, 0.2], ([0, 41, 0, 41], [41, 0, 0, 41])), shape=A.shape)
    A2 = A + near  # one new coupling between neighbours: a new analysis, with the same permutation
    f2 = f.refactor(A2)
    assert f2 is not f and f2.ordering[0] is perm and f2.ordering[1] == fill
    assert np.allclose(A2 @ f2.solve(b), b, atol=1e-9)
    with pytest.raises(RuntimeError, match="freed"):  # the replaced factor was freed before the new one was made
        f.solve(b)
    # a pattern the permutation does not suit (the grid renumbered at random): METIS orders it anew
    p = rng.permutation(n)
    B = (A[p][:, p] + 5.0 * sp.identity(n)).tocsc()
    f3 = Factor(B, "pardiso", ordering=(perm, fill))
    assert f3.ordering[0] is not perm
    assert f3.ordering[1] <= solvers.REORDER_FILL * Factor(B, "pardiso").ordering[1]
    assert np.allclose(B @ f3.solve(b), b, atol=1e-9)


@pytest.mark.parametrize("backend", ["cholespy", "scipy"])
def test_refactor_with_other_backends_is_a_new_factorization(backend):
    if backend not in available_backends():
        pytest.skip(f"{backend} not installed")
    A = _spd(seed=2)
    b = np.ones(A.shape[0])
    f = Factor(A, backend)
    A2 = 2.0 * A
    f2 = f.refactor(A2)
    assert f2 is not f and f2.backend == backend
    assert np.allclose(A2 @ f2.solve(b), b, atol=1e-9) and np.allclose(A @ f.solve(b), b, atol=1e-9)


@pytest.mark.parametrize("backend", ["scipy", "pardiso"])
def test_solve_unsymmetric(backend):
    if backend not in available_backends():
        pytest.skip(f"{backend} not installed")
    rng = np.random.default_rng(4)
    A = _spd(seed=5).tolil()
    A[3, 7] += 0.5  # no longer symmetric
    A = A.tocsc()
    b = rng.standard_normal((A.shape[0], 2))
    x = solvers.solve_unsymmetric(A, b, backend)
    assert x.shape == b.shape and np.allclose(A @ x, b, atol=1e-9)
    assert np.allclose(solvers.solve_unsymmetric(A, b[:, 0], backend), x[:, 0], atol=1e-9)


@pytest.mark.skipif("pardiso" not in available_backends(), reason="pypardiso not installed")
def test_pardiso_two_level_factorization_for_large_systems_it_orders_itself():
    """From ``TWO_LEVEL_MIN_UNKNOWNS`` unknowns PARDISO factorizes with its improved two-level algorithm where it
    orders the matrix itself (not with a permutation given, nor below that size): the solves are as accurate, a
    refactorization keeps the setting, and the same matrix gives the same bits every time (reproducible maps)."""
    rng = np.random.default_rng(5)
    k = int(np.ceil(np.sqrt(solvers.TWO_LEVEL_MIN_UNKNOWNS)))
    A = (_grid_laplacian(k) + 1e-3 * sp.identity(k * k)).tocsc()
    b = rng.standard_normal(k * k)
    f, g = Factor(A, "pardiso"), Factor(A, "pardiso")
    assert f._f.iparm[23] == 10
    x = f.solve(b)
    assert np.linalg.norm(A @ x - b) <= 1e-10 * np.linalg.norm(b)
    np.testing.assert_array_equal(x, g.solve(b))  # bit for bit
    A2 = (A + 1e-3 * sp.identity(k * k)).tocsc()  # new values on the same pattern: refactorized in place
    assert f.refactor(A2) is f and f._f.iparm[23] == 10
    assert np.linalg.norm(A2 @ f.solve(b) - b) <= 1e-10 * np.linalg.norm(b)
    assert Factor(A, "pardiso", ordering=f.ordering)._f.iparm[23] == 0
    assert Factor(_grid_laplacian(40), "pardiso")._f.iparm[23] == 0
    # a new pattern of a large system: METIS orders it anew and the factor stays two-level,
    # instead of the last permutation given (which would mean the classic algorithm)
    near = sp.coo_matrix(([-0.1, -0.1, 0.2, 0.2], ([0, k + 1, 0, k + 1], [k + 1, 0, 0, k + 1])), shape=A.shape)
    A3 = (A2 + near).tocsc()
    f3 = f.refactor(A3)
    assert f3 is not f and f3._f.iparm[23] == 10 and f3._f.iparm[4] == 2
    assert np.linalg.norm(A3 @ f3.solve(b) - b) <= 1e-10 * np.linalg.norm(b)


@pytest.mark.skipif("pardiso" not in available_backends(), reason="pypardiso not installed")
def test_a_bad_two_level_solve_falls_back_to_the_classic_factorization(monkeypatch):
    """The first solve of a two-level factor is checked (``TWO_LEVEL_BACKWARD_ERROR``); one that misses is done
    again with the classic factorization, on the same ordering, which stays for the later solves; a factor that
    passed is trusted for its later solves, a refactorization checked again."""
    rng = np.random.default_rng(6)
    k = int(np.ceil(np.sqrt(solvers.TWO_LEVEL_MIN_UNKNOWNS)))
    A = (_grid_laplacian(k) + 1e-3 * sp.identity(k * k)).tocsc()
    B = rng.standard_normal((k * k, 2))
    f = Factor(A, "pardiso")
    perm = f.ordering[0]
    real = f._f.solve
    monkeypatch.setattr(f._f, "solve", lambda T, b: real(T, b) + 1.0)  # a wrong answer from the two-level factor
    X = f.solve(B)
    assert f._f.iparm[23] == 0 and f.ordering[0] is perm
    assert np.linalg.norm(A @ X - B) <= 1e-10 * np.linalg.norm(B)
    assert np.linalg.norm(A @ f.solve(B[:, 0]) - B[:, 0]) <= 1e-10 * np.linalg.norm(B[:, 0])


@pytest.mark.skipif("pardiso" not in available_backends(), reason="pypardiso not installed")
def test_a_two_level_factor_is_checked_once_per_matrix(monkeypatch):
    """A two-level factor that solved well once is not checked again until it is refactorized (each check costs two
    products with the matrix: 20 solves of the cut beetle↑'s conformal layout share one)."""
    k = int(np.ceil(np.sqrt(solvers.TWO_LEVEL_MIN_UNKNOWNS)))
    A = (_grid_laplacian(k) + 1e-3 * sp.identity(k * k)).tocsc()
    b = np.random.default_rng(7).standard_normal(k * k)
    calls = []
    real = solvers._solved
    monkeypatch.setattr(solvers, "_solved", lambda *a: calls.append(1) or real(*a))
    f = Factor(A, "pardiso")
    for _ in range(3):
        f.solve(b)
    assert len(calls) == 1
    A2 = (A + 1e-3 * sp.identity(k * k)).tocsc()
    assert f.refactor(A2) is f
    x = f.solve(b)
    f.solve(b)
    assert len(calls) == 2 and np.linalg.norm(A2 @ x - b) <= 1e-10 * np.linalg.norm(b)


@pytest.mark.skipif("pardiso" not in available_backends(), reason="pypardiso not installed")
def test_pardiso_analysis_alone_then_a_numerical_factorization():
    rng = np.random.default_rng(4)
    A = _spd(seed=4)
    b = rng.standard_normal(A.shape[0])
    ref = Factor(A, "pardiso")
    P = sp.triu(A, format="csr")
    P.sort_indices()
    P.data[:] = 0.0  # the pattern alone: its values are not read
    f = Factor(P, "pardiso", upper=True, numeric=False)
    assert f.symbolic and f.ordering[0] is not None
    with pytest.raises(RuntimeError, match="analysis only"):
        f.solve(b)
    f2 = f.refactor(A)  # A's pattern is the analysed one: numerical factorization, in place
    assert f2 is f and not f.symbolic
    assert np.array_equal(f.ordering[0], ref.ordering[0])  # the ordering a full factorization makes
    assert np.array_equal(f.solve(b), ref.solve(b))  # the same factor: the same solution, bit for bit
    # a matrix of another pattern: analysed anew, as if the analysis had never been made
    g = Factor(P, "pardiso", upper=True, numeric=False)
    B = A + sp.coo_matrix(([-0.1, -0.1, 0.2, 0.2], ([0, 399, 0, 399], [399, 0, 0, 399])), shape=A.shape)
    assert solvers.within(P, sp.triu(B, format="csr")) is None  # (0,399) is new
    g2 = g.refactor(B)
    assert g2 is not g and not g2.symbolic
    assert np.array_equal(g2.solve(b), Factor(B, "pardiso").solve(b))
    with pytest.raises(RuntimeError, match="freed"):
        g.solve(b)
    with pytest.raises(ValueError, match="pardiso"):
        Factor(A, "scipy", numeric=False)


@pytest.mark.skipif("pardiso" not in available_backends(), reason="pypardiso not installed")
def test_classic_pardiso_factorizations_run_on_one_thread(monkeypatch):
    # the largest system PARDISO factorizes the classic way (below the two-level size: the polish's coarse levels)
    # runs every phase on one thread; the first two-level size does not
    threads = []
    real = solvers.pardiso_threads

    @contextlib.contextmanager
    def spy(solver, size):
        with real(solver, size):
            threads.append((size, solver.libmkl.MKL_Get_Max_Threads()))
            yield

    monkeypatch.setattr(solvers, "pardiso_threads", spy)
    for n in (solvers.TWO_LEVEL_MIN_UNKNOWNS - 1, solvers.TWO_LEVEL_MIN_UNKNOWNS):
        A = sp.diags([-1.0, 2.5, -1.0], [-1, 0, 1], shape=(n, n), format="csr")
        f = Factor(A, "pardiso")
        assert np.allclose(A @ f.solve(np.ones(n)), 1.0)
        assert f._f.iparm[23] == (10 if n >= solvers.TWO_LEVEL_MIN_UNKNOWNS else 0)
    outside = f._f.libmkl.MKL_Get_Max_Threads()
    assert {t for size, t in threads if size < solvers.TWO_LEVEL_MIN_UNKNOWNS} == {1}
    assert {t for size, t in threads if size >= solvers.TWO_LEVEL_MIN_UNKNOWNS} == {outside}


@pytest.mark.skipif("pardiso" not in available_backends(), reason="pypardiso not installed")
def test_small_pardiso_systems_run_on_one_thread_and_the_setting_is_restored(monkeypatch):
    A = _spd(seed=5)
    n = A.shape[0]
    b = np.random.default_rng(5).standard_normal(n)
    f = Factor(A, "pardiso")
    get = f._f.libmkl.MKL_Get_Max_Threads
    before = get()
    inside = []
    with solvers.pardiso_threads(f._f, n):  # below PARDISO_SERIAL_BELOW
        inside.append(get())
    with solvers.pardiso_threads(f._f, solvers.PARDISO_SERIAL_BELOW):
        inside.append(get())
    assert inside == [1, before] and get() == before
    # every PARDISO phase of a factor goes through it with the factor's size: analysis + factorization, the
    # numerical refactorization, the solves
    seen = []
    real = solvers.pardiso_threads

    def spy(solver, size):
        seen.append(size)
        return real(solver, size)

    monkeypatch.setattr(solvers, "pardiso_threads", spy)
    g = Factor(A, "pardiso")
    x = g.solve(b)
    assert g.refactor(A * 2.0) is g
    assert np.allclose(g.solve(b), 0.5 * x)
    assert seen == [n, n, n, n]
    # one thread or two: the same solution to rounding
    monkeypatch.setattr(solvers, "PARDISO_SERIAL_BELOW", 0)
    assert np.allclose(Factor(A, "pardiso").solve(b), x, rtol=1e-12, atol=1e-12)
