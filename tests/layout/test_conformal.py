"""The conformal layout: the spectral conformal map without pins (Mullen et al. 2008), against LSCM with pins."""

import igl
import numpy as np
import pytest

from heatparam import datasets
from heatparam.layout.conformal import SCP_TOL, conformal_layout, spectral_conformal
from heatparam.mesh.topology import boundary_loops, degenerate_faces
from heatparam.refine.start import lscm_start
from heatparam.solvers import available_backends


def _energy(V, F, uv):
    st = lscm_start(V, F, lambda: uv)
    assert st.flips == 0 and st.crossings == 0
    return st.energy


def _pinned(V, F):
    """igl.lscm with the longest loop's first vertex and the loop vertex farthest from it pinned."""
    outer = max(boundary_loops(F), key=len)
    a = int(outer[0])
    b = int(outer[np.argmax(np.linalg.norm(V[outer] - V[a], axis=1))])
    uv, _ = igl.lscm(V, F, np.array([a, b]), np.array([[0.0, 0.0], [1.0, 0.0]]))
    return np.asarray(uv, dtype=np.float64)


def test_developable_surfaces_are_laid_out_isometrically():
    for s in (datasets.cylinder_patch(h=0.1), datasets.cylinder_with_holes(h=0.1), datasets.cone_s_strip()):
        e = _energy(s.V, s.F, conformal_layout(s.V, s.F))
        assert e - 1.0 < 1e-6 and e <= _energy(s.V, s.F, _pinned(s.V, s.F)) + 1e-9


def test_no_pins_beats_two_pins_on_a_noisy_scan():
    """Scanner noise: LSCM with two far boundary vertices pinned (the layout before 2026-12-02) shrinks towards the
    pins; the spectral map does not (noisy demo part cut open: measured 1.625 pinned, 1.033 spectral)."""
    from heatparam.mesh.seams import cut_open, hole_seams

    s = datasets.noisy_scan_part()
    loops = sorted(boundary_loops(s.F), key=len, reverse=True)
    V, F, _ = cut_open(s.V, s.F, hole_seams(s.V, s.F, loops))
    e_pinned = _energy(V, F, _pinned(V, F))
    e_spectral = _energy(V, F, conformal_layout(V, F))
    assert e_spectral < 1.05 < 1.3 < e_pinned


def test_deterministic_and_turned_like_the_pins():
    """No pins fix the rotation: the layout is turned so that the longest loop's first vertex and the loop vertex
    farthest from it lie on the u axis; a rigid motion of the input gives the same layout (round-off)."""
    s = datasets.noisy_scan_part()  # no symmetry: the farthest loop vertex is one vertex, not a tie
    uv1, k = spectral_conformal(s.V, s.F)
    assert 2 <= k < 60
    assert np.array_equal(uv1, spectral_conformal(s.V, s.F)[0])
    c, si = np.cos(0.7), np.sin(0.7)
    R = np.array([[c, -si, 0.0], [si, c, 0.0], [0.0, 0.0, 1.0]])
    uv2, _ = spectral_conformal(s.V @ R.T + 3.0, s.F)
    assert np.abs(uv2 - uv1).max() < 1e-7 * np.ptp(uv1, axis=0).max()
    outer = max(boundary_loops(s.F), key=len)
    a = int(outer[0])
    b = int(outer[np.argmax(np.linalg.norm(s.V[outer] - s.V[a], axis=1))])
    assert abs(uv1[b, 1] - uv1[a, 1]) < 1e-12 and uv1[b, 0] > uv1[a, 0]


@pytest.mark.parametrize("name", ["cylinder_with_holes", "cone_s_strip"])
def test_conformal_energy_is_libigls_and_backends_agree(name):
    """The conformal energy's matrix Q is libigl's: minimized with the same two pins (holes included) it gives
    igl.lscm's map; and the spectral map is the same with every factorization backend."""
    import scipy.sparse.linalg as spla

    from heatparam.layout.conformal import _conformal_energy

    s = getattr(datasets, name)()
    n = len(s.V)
    outer = max(boundary_loops(s.F), key=len)
    pins, pin_uv = np.array([outer[0], outer[len(outer) // 2]]), np.array([[0.0, 0.0], [1.0, 0.0]])
    Q, _, _ = _conformal_energy(s.V, s.F)
    fixed = np.concatenate([pins, pins + n])
    free = np.setdiff1d(np.arange(2 * n), fixed)
    x = np.zeros(2 * n)
    x[fixed] = pin_uv.T.ravel()
    Q = Q.tocsr()
    x[free] = spla.spsolve(Q[free][:, free].tocsc(), -(Q[free][:, fixed] @ x[fixed]))
    ours = np.column_stack([x[:n], x[n:]])
    ref, _ = igl.lscm(s.V, s.F, pins, pin_uv)
    assert np.abs(ours - ref).max() <= 1e-8 * np.ptp(ref, axis=0).max()
    uv, _ = spectral_conformal(s.V, s.F)
    ext = np.ptp(uv, axis=0).max()
    for backend in available_backends():  # PARDISO too, where installed: the layouts of >= 20k unknowns use it
        # to a tenth of the method's stopping tolerance (each backend's round-off builds its own Krylov space;
        # measured 1.6e-8 of the extent, the inverse iteration 5e-11)
        assert np.abs(spectral_conformal(s.V, s.F, backend=backend)[0] - uv).max() <= 0.1 * SCP_TOL * ext



@pytest.mark.parametrize("name", ["noisy_scan_part", "cone_s_strip", "curved_cap_with_holes"])
def test_krylov_and_inverse_iteration_find_the_same_layout(name):
    """Both methods converge to the eigenplane's layout, turned alike; the block Krylov space of [x, J x] needs no
    more solves (noisy_scan_part: 5 vs 10) and its Ritz vector is an eigenvector (small residual)."""
    from heatparam.layout.conformal import _conformal_energy

    s = getattr(datasets, name)()
    uv_i, k_i = spectral_conformal(s.V, s.F, method="inverse")
    uv_k, k_k = spectral_conformal(s.V, s.F, method="krylov")
    assert k_k <= k_i
    assert np.abs(uv_k - uv_i).max() < 1e-6 * np.ptp(uv_i, axis=0).max()
    Q, mass, _ = _conformal_energy(s.V, s.F)
    b = np.concatenate([mass, mass])
    x = uv_k.T.ravel()
    lam = x @ (Q @ x) / (x @ (b * x))
    r = Q @ x - lam * (b * x)
    assert np.linalg.norm(r) < 1e-6 * abs(Q).max() * np.linalg.norm(x)  # relative to Q's scale (λ may be ~0)


def test_unknown_method_is_refused():
    s = datasets.cone_s_strip()
    with pytest.raises(ValueError, match="method"):
        spectral_conformal(s.V, s.F, method="lanczos")


@pytest.mark.parametrize("method", ["krylov", "inverse"])
def test_max_solves_caps_the_iteration(method):
    """The seams stage's cut meshes stop the inverse iteration early (SCP_CUT_MAX_ITERS): the cap holds for both
    methods, and a capped layout is still a layout (finite, turned like the converged one)."""
    s = datasets.noisy_scan_part()  # 10 inverse / 5 Krylov solves to converge
    uv, k = spectral_conformal(s.V, s.F, method=method, max_solves=2)
    assert k == 2 and np.isfinite(uv).all()
    full, k_full = spectral_conformal(s.V, s.F, method=method)
    assert k_full > 2
    assert np.abs(uv - full).max() < 0.5 * np.ptp(full, axis=0).max()


def _with_border_sliver(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(V, F) with a zero-area face on a boundary edge (a, b): its midpoint m splits a b's face in two, and the
    face (b, m, a), flat on the segment, takes the edge over (the slivers of the large-part family's scans)."""
    a, b = boundary_loops(F)[0][:2]  # a → b as oriented in its face
    f = int(np.flatnonzero(((F == a) | (F == b)).sum(axis=1) == 2)[0])
    c = int(np.setdiff1d(F[f], [a, b])[0])
    m = len(V)
    F2 = np.vstack([np.delete(F, f, axis=0), [[a, m, c], [m, b, c], [b, m, a]]])
    return np.vstack([V, 0.5 * (V[a] + V[b])]), F2


def test_zero_area_faces_take_the_mollified_cotangents():
    s = datasets.cylinder_patch()
    V, F = _with_border_sliver(s.V, s.F)
    assert degenerate_faces(V, F).sum() == 1 and not np.isfinite(igl.cotmatrix(V, F).data).all()
    uv = conformal_layout(V, F)
    assert np.isfinite(uv).all()
    st = lscm_start(V, F, lambda: uv)  # a start the polish can take: bijective once the sliver is repaired
    assert st.energy is not None and st.near_isometric


def test_smoothed_layout_keeps_the_true_area_and_unfolds_border_spikes():
    from heatparam.layout.conformal import smoothed_conformal_layout
    from heatparam.mesh.planar import signed_areas
    from heatparam.mesh.topology import face_areas
    from heatparam.refine.energy import surface_gradients
    from heatparam.refine.start import bijectivity

    from conftest import spiked_cylinder

    V, F = spiked_cylinder()
    g, _ = surface_gradients(V, F)
    assert bijectivity(conformal_layout(V, F), F, g) != (0, 0)  # the spikes fold the border
    uv = smoothed_conformal_layout(V, F, 4)
    assert bijectivity(uv, F, g) == (0, 0)
    assert np.isclose(signed_areas(uv, F).sum(), face_areas(V, F).sum(), rtol=1e-9)  # V's area, not the smoothed
    np.testing.assert_array_equal(smoothed_conformal_layout(V, F, 0), conformal_layout(V, F))


@pytest.mark.skipif("pardiso" not in available_backends(), reason="PARDISO is not installed")
def test_layouts_of_one_triangulation_refactorize_the_kept_factor_to_the_same_layouts():
    from heatparam.layout.conformal import ConformalLayouts, smoothed_conformal_layout

    s = datasets.cylinder_with_holes(h=0.018)  # ≥ 20k unknowns: PARDISO
    assert 2 * len(s.V) >= 20_000
    rng = np.random.default_rng(3)
    V = s.V + 0.002 * rng.standard_normal(s.V.shape)
    layouts = ConformalLayouts(s.F)
    first = layouts.layout(V)
    kept = layouts._fac
    smoothed = layouts.smoothed(V, 4)
    assert layouts._fac is kept and not kept.symbolic  # the same object, refactorized in place
    np.testing.assert_array_equal(first, conformal_layout(V, s.F))
    np.testing.assert_array_equal(smoothed, smoothed_conformal_layout(V, s.F, 4))
    layouts.free()
    assert layouts._fac is None
    np.testing.assert_array_equal(layouts.layout(V), first)  # factorized anew
    layouts.free()


def test_a_surface_frees_its_conformal_factor_after_the_smoothed_layout():
    from heatparam.pipeline.surface import Surface

    s = datasets.cylinder_with_holes(h=0.1)
    surface, _, _ = Surface.validated(s.V, s.F)
    surface.conformal()
    assert surface._layouts._fac is not None  # kept for the smoothed layout
    surface.smoothed_conformal(4)
    assert surface._layouts._fac is None
    surface.release_layouts()  # nothing left to free: no error
