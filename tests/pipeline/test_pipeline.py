import numpy as np
import pytest

from heatparam import datasets, metrics, options
from heatparam.errors import HeatparamError
from heatparam.pipeline import Options, parameterize


@pytest.fixture(scope="module")
def cylinder():
    return datasets.cylinder_patch()


def test_convex_developable_patch_true_scale(cylinder):
    """Issue 2 acceptance: the paper's raw MDS map of a cylinder patch (all-pairs, no refinement)."""
    uv, rep = parameterize(cylinder.V, cylinder.F, geodesics="all-pairs", fill="none", refine="none")
    m = rep["metrics"]
    assert m["flips"] == 0 and m["boundary_crossings"] == 0
    assert m["iso_mean"] <= 1.10
    err = metrics.layout_error(uv, cylinder.uv_true)  # rigid motion only: a wrong scale fails this
    print(f"cylinder raw MDS: iso {m['iso_mean']:.4f}, layout error {err:.4f}, uv_scale {m['uv_scale']:.4f}")
    assert err <= 0.02
    assert rep["method"]["geodesics"] == "all-pairs"


def test_landmark_path_matches_all_pairs_quality(cylinder):
    """Issue 4 acceptance: landmark MDS gives the same map quality as all-pairs (mean iso within 1%)."""
    _, ra = parameterize(cylinder.V, cylinder.F, geodesics="all-pairs", fill="none", refine="none")
    _, rl = parameterize(cylinder.V, cylinder.F, geodesics="landmarks", fill="none", refine="none")
    ia, il = ra["metrics"]["iso_mean"], rl["metrics"]["iso_mean"]
    print(f"iso all-pairs {ia:.4f}, landmarks {il:.4f}")
    assert abs(il - ia) / ia <= 0.01
    assert rl["method"]["geodesics"] == "landmarks" and rl["parameters"]["landmarks_used"] == 100


def test_scale_invariance_default_vs_paper(cylinder):
    """Default t = c·h² gives the same map (up to the scale) for a mesh scaled by 1000; Eq. 7 does not."""
    def run(V, ts):
        uv, _ = parameterize(V, cylinder.F, geodesics="all-pairs", fill="none", refine="none", time_step=ts)
        return uv

    uv1, uv2 = run(cylinder.V, "default"), run(1000 * cylinder.V, "default")
    assert metrics.layout_error(uv2 / 1000, uv1) < 1e-6
    p1, p2 = run(cylinder.V, "paper"), run(1000 * cylinder.V, "paper")
    diff = metrics.layout_error(p2 / 1000, p1)
    print(f"paper time step: scaled-map difference {diff:.4f} of the diameter")
    assert diff > 1e-3


def test_deterministic_with_seed():
    sh = datasets.flat_square()
    a, _ = parameterize(sh.V, sh.F, geodesics="landmarks", seed=5, refine="none", fill="none")
    b, _ = parameterize(sh.V, sh.F, geodesics="landmarks", seed=5, refine="none", fill="none")
    assert np.array_equal(a, b)


def test_unreferenced_vertices_kept_with_warning(cylinder):
    V = np.vstack([cylinder.V, [[9.0, 9.0, 9.0]]])
    uv, rep = parameterize(V, cylinder.F, fill="none", refine="none")
    assert uv.shape == (len(V), 2) and np.isfinite(uv).all()
    assert rep["mesh"]["unreferenced_vertices"] == 1
    assert any("unreferenced" in w for w in rep["warnings"])


def test_report_fields(cylinder):
    _, rep = parameterize(cylinder.V, cylinder.F, fill="none", refine="none")
    for key in ("parameters", "timings_s", "mesh", "metrics", "method", "warnings", "peak_rss_mb"):
        assert key in rep
    for key in ("flips", "boundary_crossings", "iso_mean", "iso_p95", "conformal_mean", "area_mean",
                "stress_rel_rms"):
        assert key in rep["metrics"]
    for key in ("vertices", "faces", "boundary_loops", "holes"):
        assert key in rep["mesh"]
    assert {"validate", "operators", "factorize", "geodesics", "mds", "metrics"} <= set(rep["timings_s"])
    assert 0 < rep["metrics"]["stress_rel_rms"] < 0.1


def test_bad_options_rejected(cylinder):
    with pytest.raises(HeatparamError, match="geodesics"):
        parameterize(cylinder.V, cylinder.F, geodesics="bogus")
    with pytest.raises(HeatparamError, match="landmarks"):
        parameterize(cylinder.V, cylinder.F, landmarks=2)
    with pytest.raises(TypeError):
        Options(bogus=1)


def test_default_pipeline_deterministic():
    """Fill, landmarks and refinement with the same seed: bit-identical output."""
    sh = datasets.cylinder_with_holes(h=0.09)
    a, ra = parameterize(sh.V, sh.F, seed=3, mds_start="always")
    b, rb = parameterize(sh.V, sh.F, seed=3, mds_start="always")
    assert ra["method"]["fill"]["used"] and ra["method"]["refine"]["method"] == "sd"
    assert np.array_equal(a, b)


@pytest.mark.slow
def test_default_pipeline_reproducible_across_processes():
    """The same input and seed give a bit-identical map in two fresh processes, with the default backends
    (camelhead: PARDISO's threaded factorization gave a different map in every run before MKL's conditional
    numerical reproducibility was switched on; see solvers.prepare_mkl)."""
    import os
    import subprocess
    import sys

    from conftest import shared_mesh

    mesh = shared_mesh("camelhead.off")
    code = ("import hashlib, sys; from heatparam import formats, pipeline; V, F = formats.load_mesh(sys.argv[1]); "
            "uv, rep = pipeline.parameterize(V, F, seed=1); "
            "print(hashlib.sha1(uv.tobytes()).hexdigest(), rep['method']['refine']['polish']['backend'])")
    env = {k: v for k, v in os.environ.items() if k != "MKL_CBWR"}  # as a user's shell would be
    runs = [subprocess.run([sys.executable, "-c", code, str(mesh)], capture_output=True, text=True, env=env,
                           check=True).stdout.split() for _ in range(2)]
    assert runs[0] == runs[1], runs


def test_near_isometric_lscm_skips_the_heat_stage_same_map():
    """Developable with holes: LSCM is bijective and isometric to round-off, so the default skips fill, geodesics
    and MDS, and the map is bit-identical to the one computed with them (``mds_start="always"``)."""
    sh = datasets.cylinder_with_holes(h=0.09)
    fast, rf = parameterize(sh.V, sh.F)
    full, ra = parameterize(sh.V, sh.F, mds_start="always")
    assert np.array_equal(fast, full)
    assert ra["method"]["refine"]["start"]["layout"] == "conformal" and ra["method"]["fill"]["used"]
    assert rf["method"]["geodesics"].startswith("skipped") and "skipped" in rf["method"]["fill"]
    assert not rf["method"]["fill"]["used"] and "geodesics" not in rf["timings_s"]
    assert rf["metrics"]["stress_rel_rms"] is None and ra["metrics"]["stress_rel_rms"] > 0
    assert rf["method"]["refine"]["start"]["energy"]["conformal"] - 1 < options.ISOMETRIC_START_EXCESS


def test_curved_surface_keeps_the_heat_stage():
    """A spherical cap (LSCM 1% above an isometry): the MDS layout is computed and competes as a start."""
    d = datasets.flat_disk(h=0.08)
    V = datasets.lift_sphere(d.V[:, :2], 1.2)
    _, rep = parameterize(V, d.F)
    start = rep["method"]["refine"]["start"]
    assert start["energy"]["conformal"] - 1 > options.ISOMETRIC_START_EXCESS and "mds" in start["energy"]
    assert "geodesics" in rep["timings_s"] and rep["metrics"]["stress_rel_rms"] > 0


def test_explicit_heat_options_are_never_skipped():
    sh = datasets.cylinder_with_holes(h=0.09)
    for kw in ({"fill": "biharmonic"}, {"geodesics": "landmarks"}, {"landmarks": 20}, {"stress": "smacof"}):
        _, rep = parameterize(sh.V, sh.F, **kw)
        assert "geodesics" in rep["timings_s"], kw


@pytest.mark.slow
def test_folded_mds_large_mesh_skips_the_heat_stage_same_map(monkeypatch):
    """camelhead (MDS folds, the conformal start is bijective): counted as large, the heat stage is skipped and the
    map is bit-identical to the one computed with it (the start is the conformal layout either way)."""
    from heatparam import formats
    from heatparam.pipeline import shortcuts

    from conftest import shared_mesh

    V, F = formats.load_mesh(shared_mesh("camelhead.off"))
    monkeypatch.setattr(shortcuts, "CONFORMAL_START_MIN_VERTICES", 5000)
    fast, rf = parameterize(V, F)
    full, ra = parameterize(V, F, mds_start="always")
    assert np.array_equal(fast, full)
    assert rf["method"]["geodesics"].startswith("skipped: the conformal layout is bijective")
    assert "geodesics" not in rf["timings_s"]
    assert ra["method"]["refine"]["start"]["flips"] > 0 and ra["method"]["refine"]["start"]["layout"] == "conformal"


def test_large_mesh_with_a_bijective_conformal_start_skips_the_heat_stage(monkeypatch):
    """The noisy demo part counted as large (its conformal layout bijective, 0.3% above an isometry): the heat stage
    is skipped and the map has the quality of the one computed with it (iso mean within 1e-5, both bijective)."""
    from heatparam.pipeline import shortcuts

    s = datasets.noisy_scan_part()
    monkeypatch.setattr(shortcuts, "CONFORMAL_START_MIN_VERTICES", 1000)
    _, rf = parameterize(s.V, s.F)
    _, ra = parameterize(s.V, s.F, mds_start="always")
    assert rf["method"]["geodesics"].startswith("skipped: the conformal layout is bijective")
    assert "geodesics" not in rf["timings_s"] and "geodesics" in ra["timings_s"]
    assert rf["metrics"]["flips"] == 0 and rf["metrics"]["boundary_crossings"] == 0
    assert rf["metrics"]["iso_mean"] == pytest.approx(ra["metrics"]["iso_mean"], abs=1e-5)
    monkeypatch.setattr(shortcuts, "CONFORMAL_START_MIN_VERTICES", len(s.V) + 1)  # below the size: it runs
    _, rs = parameterize(s.V, s.F)
    assert "geodesics" in rs["timings_s"]


def test_large_mesh_whose_conformal_layout_folds_keeps_the_heat_stage(monkeypatch, halftunnel):
    """halftunnel's conformal layout has flipped faces: MDS may be the only bijective start, so the heat stage runs
    whatever the size."""
    from heatparam.pipeline import shortcuts

    V, F = halftunnel
    monkeypatch.setattr(shortcuts, "CONFORMAL_START_MIN_VERTICES", 100)
    _, rep = parameterize(V, F, seams="none", refine_iters=1)
    assert rep["method"]["refine"]["start"]["conformal_flips"] > 0
    assert "geodesics" in rep["timings_s"] and not rep["method"]["geodesics"].startswith("skipped")


def test_seam_trial_on_a_large_mesh_without_a_conformal_start_skips_the_heat_stage(monkeypatch, halftunnel):
    """Case (d): halftunnel counted as large, seams auto: its map without seams is the seams stage's trial and its
    conformal layout is not bijective even repaired, so the trial skips the heat stage (MDS folded there too) and
    starts from Tutte; the cut map is kept, as with the heat stage computed (``mds_start='always'``), bijective and
    as close to an isometry."""
    from heatparam.pipeline import shortcuts

    V, F = halftunnel
    monkeypatch.setattr(shortcuts, "CONFORMAL_START_MIN_VERTICES", 100)
    fast = parameterize(V, F)
    full = parameterize(V, F, mds_start="always")
    rf, ra = fast.report, full.report
    assert rf["method"]["seams"]["used"] and ra["method"]["seams"]["used"]
    assert "geodesics" not in rf["timings_s"] and "geodesics" in ra["timings_s"]
    assert rf["method"]["seams"]["iso_mean_without"] > rf["method"]["seams"]["iso_mean_with"]
    assert rf["metrics"]["bijective"] and rf["metrics"]["iso_mean"] == pytest.approx(ra["metrics"]["iso_mean"],
                                                                                        rel=1e-3)


def test_large_mesh_whose_conformal_layout_is_repaired_skips_the_heat_stage(monkeypatch):
    """A conformal layout with a few flipped faces, repaired as MDS's are, is a bijective start: counted as large,
    the heat stage is skipped (a 182k-vertex such part: 274 -> 84 s, BENCHMARKS §18), and the map has the quality of
    the one computed with it."""
    from heatparam.pipeline import shortcuts

    V, F = _noisy_cylinder_with_holes(0.3, vertices=5000)
    monkeypatch.setattr(shortcuts, "CONFORMAL_START_MIN_VERTICES", 1000)
    _, rf = parameterize(V, F, seams="none")
    _, ra = parameterize(V, F, seams="none", mds_start="always")
    st = rf["method"]["refine"]["start"]
    assert st["conformal_flips"] > 0 and st["conformal_repair"]["repaired"] and st["layout"] == "conformal"
    assert "flipped faces repaired" in rf["method"]["geodesics"] and "geodesics" not in rf["timings_s"]
    assert rf["metrics"]["flips"] == 0 and rf["metrics"]["boundary_crossings"] == 0
    assert rf["metrics"]["iso_mean"] == pytest.approx(ra["metrics"]["iso_mean"], abs=1e-4)


def test_a_failed_optional_heat_stage_falls_back_to_the_other_starts(monkeypatch):
    """The heat stage only offers a start (mds_start auto): when it fails numerically (a noisy 182k scan's fill
    surface once made NaN cotangents, PARDISO -4) the map starts from the conformal layout, with a warning; asked
    for (mds_start='always'), its failure is the answer."""
    from heatparam.pipeline import heat_stage

    def failing(*args, **kwargs):
        raise HeatparamError("the heat method's systems could not be factorized (test)")

    V, F = _noisy_cylinder_with_holes(0.3, vertices=5000)
    monkeypatch.setattr(heat_stage, "geodesic_layout", failing)
    _, rep = parameterize(V, F, seams="none")
    assert rep["method"]["geodesics"].startswith("skipped: the heat stage failed")
    assert any("heat stage failed" in w for w in rep["warnings"])
    assert rep["metrics"]["flips"] == 0 and rep["method"]["refine"]["start"]["layout"] == "conformal"
    with pytest.raises(HeatparamError, match="could not be factorized"):
        parameterize(V, F, seams="none", mds_start="always")


def test_noisy_developable_scan_starts_from_the_lower_energy_layout():
    """Scanner-like noise (0.2 × the edge length on every coordinate): the heat stage runs (the conformal layout is
    not near-isometric), both candidates are bijective and the refinement starts from the lower-energy one. LSCM
    with two pins had energy 1.53 here (MDS 1.02 then started); the spectral conformal map without pins stays
    close to an isometry (measured 1.014, MDS 1.022). The map is bijective, and the default's start checks do not
    change it."""
    s = datasets.cylinder_patch()
    h = float(np.mean(np.linalg.norm(s.V[s.F[:, 1]] - s.V[s.F[:, 0]], axis=1)))
    V = s.V + 0.2 * h * np.random.default_rng(1).standard_normal(s.V.shape)
    uv, rep = parameterize(V, s.F)
    st = rep["method"]["refine"]["start"]
    assert set(st["energy"]) == {"mds", "conformal"} and st["layout"] == min(st["energy"], key=st["energy"].get)
    assert st["energy"]["conformal"] < 1.1 and st["energy"]["mds"] < 1.1
    assert rep["metrics"]["flips"] == 0 and rep["metrics"]["boundary_crossings"] == 0
    assert rep["metrics"]["iso_mean"] < 1.06  # measured 1.0554
    full, _ = parameterize(V, s.F, mds_start="always")
    assert np.array_equal(uv, full)


# ----------------------------------------------------------------------------------------------------------
# seams (issue 5: crossings resolved by cutting, the last resort, where the holes cost distortion)
# ----------------------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def halftunnel():
    from heatparam import formats

    from conftest import shared_mesh

    return formats.load_mesh(shared_mesh("halftunnel.off"))


@pytest.fixture(scope="module")
def halftunnel_maps(halftunnel):
    V, F = halftunnel
    return parameterize(V, F), parameterize(V, F, seams="none")


def _slim_from_tutte(V, F, iters=100):
    """libigl SLIM (symmetric Dirichlet, 100 iterations) from a Tutte start: the peer of issue 5."""
    import igl

    from heatparam.mesh import loops_outer_first

    b = loops_outer_first(V, F)[0]
    uv0 = igl.harmonic(V, F, b, igl.map_vertices_to_circle(V, b.astype(np.int32)), 1)
    data = igl.slim_precompute(V, F.astype(np.int32), uv0, igl.MappingEnergyType.SYMMETRIC_DIRICHLET,
                               np.zeros(0, np.int32), np.zeros((0, 2)))
    return np.asarray(igl.slim_solve(data, iters))[:, :2]


def test_seams_cut_the_holes_where_they_cost_distortion(halftunnel, halftunnel_maps):
    """halftunnel: the bijective map without seams has to squeeze the band between a hole and the border
    (iso 1.536); libigl SLIM lets that hole's side cross the border instead (flip-free, not bijective). The
    default cuts both holes open to the border: bijective and below SLIM's distortion, measured here."""
    from heatparam import metrics

    V, F = halftunnel
    cut, whole = halftunnel_maps
    s = cut.report["method"]["seams"]
    assert s["used"] and s["seams"] == 2 and s["split_vertices"] > 0 and not whole.seamed
    assert cut.seamed and cut.uv.shape == (len(V) + s["split_vertices"], 2) and cut.Fuv.shape == F.shape
    assert np.array_equal(cut.uv_vertex[cut.Fuv], F)  # every corner's UV row belongs to that corner's vertex
    m, mw = cut.report["metrics"], whole.report["metrics"]
    assert m["flips"] == 0 and m["boundary_crossings"] == 0 and mw["bijective"]
    # decided where the polish without seams paused (seams._decide): its iso mean there, above the finished one's
    assert s["paused"]["maps"] == ["without"]
    assert s["iso_mean_without"] > mw["iso_mean"] and s["iso_mean_with"] == m["iso_mean"]
    assert m["iso_mean"] <= (1 - 0.02) * mw["iso_mean"]
    again = metrics.summary(V, F, cut.uv, cut.Fuv)  # the report's metrics are those of the written map
    assert again["iso_mean"] == pytest.approx(m["iso_mean"], rel=1e-12) and again["bijective"]
    assert any("seams" in w for w in cut.report["warnings"])
    without = cut.report["method"]["without_seams"]
    assert without["metrics"]["iso_mean"] == s["iso_mean_without"] and without["refine"]["polish"]["stop"] == "paused"
    assert without["metrics"]["bijective"]
    slim = metrics.summary(V, F, _slim_from_tutte(V, F))
    print(f"halftunnel iso: seams {m['iso_mean']:.4f}, none {mw['iso_mean']:.4f}, SLIM {slim['iso_mean']:.4f} "
          f"({slim['flips']} flips, {slim['boundary_crossings']} crossings)")
    assert slim["flips"] == 0 and m["iso_mean"] <= slim["iso_mean"]


def test_seams_none_and_no_holes_keep_one_uv_per_vertex(halftunnel, halftunnel_maps, cylinder):
    V, F = halftunnel
    whole = halftunnel_maps[1]
    assert whole.uv.shape == (len(V), 2) and np.array_equal(whole.Fuv, F)
    assert whole.report["method"]["seams"] == {"mode": "none", "used": False, "reason": "disabled (seams='none')"}
    r = parameterize(cylinder.V, cylinder.F)
    assert r.report["method"]["seams"]["reason"] == "no holes" and np.array_equal(r.uv_vertex, np.arange(len(r.uv)))


def test_seams_auto_leaves_near_isometric_parts_with_holes_uncut():
    sh = datasets.cylinder_with_holes()
    r = parameterize(sh.V, sh.F)
    s = r.report["method"]["seams"]
    assert not s["used"] and "near-isometric" in s["reason"] and r.uv.shape == (len(sh.V), 2)
    h = parameterize(sh.V, sh.F, seams="holes")  # asked for: cut, and still an isometry (a developable part)
    assert h.seamed and h.report["metrics"]["bijective"] and h.report["metrics"]["iso_mean"] < 1.001
    assert h.report["method"]["fill"]["used"] is False and "seams" in h.report["method"]["fill"]["reason"]
    assert metrics.layout_error(h.uv, sh.uv_true[h.uv_vertex]) < 1e-3


def _noisy_cylinder_with_holes(noise: float = 0.15, vertices: int | None = None):
    """The cylinder patch with holes plus Gaussian noise of ``noise`` × the edge length; with ``vertices``, made at
    about that many vertices (noise × the measured mean edge; 0.3 at 5000: 4.9k vertices, 7 flipped faces in the
    conformal layout, which the repair fixes)."""
    if vertices is None:
        s, h = datasets.cylinder_with_holes(), 0.045
    else:
        s = datasets.cylinder_with_holes(h=0.045 * np.sqrt(2101 / vertices))
        h = float(np.mean(np.linalg.norm(s.V[s.F[:, 1]] - s.V[s.F[:, 0]], axis=1)))
    return s.V + noise * h * np.random.default_rng(0).standard_normal(s.V.shape), s.F


def test_seams_not_tried_where_no_cut_map_could_be_kept(monkeypatch):
    """An iso mean is at least 1, so a cut map can only be kept (2% lower) when the map without seams is above
    1 / 0.98: the noisy cylinder with holes (noise 0.1 × the edge length, iso mean 1.013) is not cut open at all
    now; with the old threshold (1%) the cut trial ran and lost, and the kept map is the same bit for bit."""
    from heatparam import options
    from heatparam.pipeline import seams

    V, F = _noisy_cylinder_with_holes(0.1)
    r = parameterize(V, F)
    s = r.report["method"]["seams"]
    assert not s["used"] and "iso_mean_with" not in s and "no cut map could" in s["reason"]
    assert 1.01 < r.report["metrics"]["iso_mean"] <= 1 + options.SEAM_TRY_EXCESS
    monkeypatch.setattr(seams, "SEAM_TRY_EXCESS", 0.01)
    old = parameterize(V, F)
    so = old.report["method"]["seams"]
    assert not so["used"] and so["iso_mean_with"] > so["iso_mean_without"] * (1 - options.SEAM_MIN_GAIN)
    assert np.array_equal(r.uv, old.uv) and r.report["metrics"] == old.report["metrics"]


def test_seams_not_tried_where_the_coarse_level_is_near_an_isometry(monkeypatch):
    """Scan noise, not the holes, makes the map far from an isometry (noise 0.2 × the edge length, iso mean 1.054)
    while its coarse level (coarse-to-fine forced: 10k-vertex threshold, 2.3k coarse vertices) is within 1.7% of
    one: no cut could lower the iso mean by 2% (``seams.noise_bound``), so the cut is not tried; with the trial
    (the bound switched off) the cut map lost and the kept map is the same bit for bit."""
    from heatparam import options
    from heatparam.pipeline import seams
    from heatparam.refine import multilevel

    V, F = _noisy_cylinder_with_holes(0.2, 12_000)
    monkeypatch.setattr(multilevel, "COARSE_MIN", 1500)
    r = parameterize(V, F, refine_multilevel=10_000)
    s, ml = r.report["method"]["seams"], r.report["method"]["refine"]["multilevel"]
    assert not s["used"] and "iso_mean_with" not in s and "noise" in s["reason"]
    assert r.report["metrics"]["iso_mean"] > 1 + options.SEAM_TRY_EXCESS  # the old rule would have tried the cut
    assert ml["coarse_iso_mean"] - 1 < options.SEAM_MIN_GAIN * r.report["metrics"]["iso_mean"]
    monkeypatch.setattr(seams, "noise_bound", lambda flat: None)
    old = parameterize(V, F, refine_multilevel=10_000)
    so = old.report["method"]["seams"]
    assert not so["used"] and so["iso_mean_with"] > so["iso_mean_without"] * (1 - options.SEAM_MIN_GAIN)
    assert np.array_equal(r.uv, old.uv) and r.report["metrics"] == old.report["metrics"]


def test_noise_bound_needs_a_bijective_coarse_to_fine_map():
    """The bound reads the map without seams' coarse level: none (no coarse level, a map that is not bijective, a
    coarse level too far from an isometry) → no verdict; a paused map is judged by its lowest finished value."""
    from heatparam.pipeline import seams
    from heatparam.pipeline.report import Flat

    def flat(coarse, iso=1.056, used=True, bijective=True, paused=False):
        ml = {"used": used, "coarse_vertices": 2000} | ({} if coarse is None else {"coarse_iso_mean": coarse})
        return Flat(None, {"iso_mean": iso, "bijective": bijective}, {"refine": {"multilevel": ml}}, None, None, [],
                    (lambda: None) if paused else None)

    assert seams.noise_bound(flat(1.015)) is not None
    for f in (flat(None), flat(1.015, used=False), flat(1.015, bijective=False), flat(1.025)):
        assert seams.noise_bound(f) is None
    # paused at 1.056: it may finish as low as 1 + 0.75 × 0.056 = 1.042, and 2% of that is 0.02084
    assert seams.noise_bound(flat(1.0205, paused=True)) is not None
    assert seams.noise_bound(flat(1.0209, paused=True)) is None
    assert seams.noise_bound(flat(1.0209)) is not None


@pytest.mark.parametrize("case", ["halftunnel", "noisy cylinder"])
def test_seams_decided_on_paused_polishes_keep_the_map(case, halftunnel, halftunnel_maps, monkeypatch):
    """``seams auto`` decides where the trial polishes paused when no finished value could change the answer: the
    kept map is the one decided on finished polishes, bit for bit. halftunnel keeps the cut map (the uncut polish
    paused after 8 of its 38 iterations), the noisy cylinder with holes (noise 0.15 × the edge length, iso mean 1.030)
    keeps the uncut one (the cut trial paused)."""
    from heatparam.pipeline import seams

    V, F = halftunnel if case == "halftunnel" else _noisy_cylinder_with_holes()
    paused = halftunnel_maps[0] if case == "halftunnel" else parameterize(V, F)
    monkeypatch.setattr(seams, "SEAM_PAUSE_EXCESS", 0.0)  # both trials polished to the end
    full = parameterize(V, F)
    assert np.array_equal(paused.uv, full.uv) and np.array_equal(paused.Fuv, full.Fuv)
    assert paused.report["metrics"] == full.report["metrics"]
    sp, sf = paused.report["method"]["seams"], full.report["method"]["seams"]
    assert sp["used"] == sf["used"] == (case == "halftunnel") and "paused" not in sf
    assert sp["paused"]["maps"] == (["without"] if case == "halftunnel" else ["with"])
    kept, other = ("iso_mean_with", "iso_mean_without") if sp["used"] else ("iso_mean_without", "iso_mean_with")
    assert sp[kept] == sf[kept] and sp[other] >= sf[other]  # the paused one: not below its finished value
    for key in ("iterations", "energy_end", "stop"):
        assert paused.report["method"]["refine"]["polish"][key] == full.report["method"]["refine"]["polish"][key]


def test_a_dropped_cut_trial_frees_its_factorization_before_the_kept_map_is_finished(monkeypatch):
    """The cut trial pauses without parking (``PolishSettings(park=False)``: it is usually kept and goes on at once);
    where the map without seams is kept instead (the noisy cylinder with holes), the cut trial and its factorization are
    gone by the time the kept map's polish is finished, and the kept map is the one decided on finished polishes."""
    import weakref

    from heatparam.pipeline import seams
    from heatparam.refine import newton

    made = []
    init = newton.Polish.__init__

    def recording(self, *a, **k):
        init(self, *a, **k)
        made.append(weakref.ref(self))

    monkeypatch.setattr(newton.Polish, "__init__", recording)
    held_at_finish = []
    finished = seams._finished

    def checking(f):
        if f.resume is not None:
            held_at_finish.append([p() for p in made
                                   if p() is not None and not p().settings.park and p().fac is not None])
        return finished(f)

    monkeypatch.setattr(seams, "_finished", checking)
    V, F = _noisy_cylinder_with_holes()
    paused = parameterize(V, F)
    sp = paused.report["method"]["seams"]
    assert not sp["used"] and sp["paused"]["maps"] == ["with"]  # the cut trial paused, and was dropped
    assert held_at_finish and held_at_finish[-1] == []  # no unparked factorization left when the kept map went on
    monkeypatch.setattr(seams, "SEAM_PAUSE_EXCESS", 0.0)  # both trials polished to the end
    full = parameterize(V, F)
    assert np.array_equal(paused.uv, full.uv)


def test_seams_decided_where_the_uncut_coarse_level_paused(halftunnel, monkeypatch):
    """Coarse-to-fine (forced on halftunnel: 400-vertex threshold, ~250-vertex coarse mesh), the map without seams
    pauses at its coarse level too (``seams.seam_pause``; its map there is far above ``pause_coarse``) and the
    decision is taken on the provisional fine map from it: the kept cut map is bit for bit the one decided on
    finished polishes, and the dropped one was never finished."""
    from heatparam.pipeline import seams
    from heatparam.refine import multilevel

    V, F = halftunnel
    monkeypatch.setattr(multilevel, "COARSE_MIN", 250)
    paused = parameterize(V, F, refine_multilevel=400)
    monkeypatch.setattr(seams, "SEAM_PAUSE_EXCESS", 0.0)  # both trials polished to the end
    full = parameterize(V, F, refine_multilevel=400)
    assert np.array_equal(paused.uv, full.uv) and np.array_equal(paused.Fuv, full.Fuv)
    assert paused.report["metrics"] == full.report["metrics"]
    sp = paused.report["method"]["seams"]
    assert sp["used"] and sp["paused"]["maps"] == ["without"]
    ml = paused.report["method"]["without_seams"]["refine"]["multilevel"]
    ml_full = full.report["method"]["without_seams"]["refine"]["multilevel"]
    assert ml["coarse_polish"]["stop"] == "paused" and ml_full["coarse_polish"]["stop"] != "paused"
    assert ml["coarse_polish"]["iterations"] < ml_full["coarse_polish"]["iterations"]
    assert sp["iso_mean_without"] >= full.report["method"]["seams"]["iso_mean_without"]


def test_a_seams_trial_starts_from_its_raw_prolongation_a_requested_cut_from_a_smoothed_one(halftunnel,
                                                                                              monkeypatch):
    """Coarse-to-fine forced on halftunnel: the cut map of ``seams auto`` is a trial, judged against a provisional
    map without seams, and its fine level starts from the raw prolongation (``Pausing.raw_start``); the cut map of
    ``seams holes`` is no trial, and its start is smoothed (``refine.smoother``), to a lower energy."""
    from heatparam.refine import multilevel

    V, F = halftunnel
    monkeypatch.setattr(multilevel, "COARSE_MIN", 400)  # the cut mesh's 142 boundary vertices: under half of it
    auto = parameterize(V, F, refine_multilevel=400)
    holes = parameterize(V, F, refine_multilevel=400, seams="holes")
    assert auto.report["method"]["seams"]["used"] and holes.report["method"]["seams"]["used"]
    ml = auto.report["method"]["refine"]["multilevel"]
    assert ml["used"] and "smoothing" not in ml
    sm = holes.report["method"]["refine"]["multilevel"]["smoothing"]
    assert sm["sweeps"] >= 1 and sm["energy_after"] < sm["energy_before"]
    assert holes.report["method"]["refine"]["polish"]["energy_start"] == pytest.approx(sm["energy_after"])
    assert holes.report["metrics"]["bijective"]


def test_seams_deterministic(halftunnel, halftunnel_maps):
    V, F = halftunnel
    again = parameterize(V, F)
    assert np.array_equal(again.uv, halftunnel_maps[0].uv) and np.array_equal(again.Fuv, halftunnel_maps[0].Fuv)


def test_a_stretched_one_piece_map_says_how_to_get_pieces():
    """A nearly hemispherical cap flattened in one piece stretches past the atlas's bound: a warning says how much
    and what to ask for; a developable patch gets no such warning."""
    s = datasets.flat_disk(radius=1.0, h=0.1)
    cap = parameterize(datasets.lift_sphere(s.V[:, :2], 1.05), s.F)
    said = [w for w in cap.report["warnings"] if "stretches" in w]
    assert len(said) == 1 and "max_distortion=1.05" in said[0]
    assert f"{cap.report['metrics']['iso_mean']:.3f}" in said[0]
    flat = datasets.cylinder_patch(h=0.1)
    assert not [w for w in parameterize(flat.V, flat.F).report["warnings"] if "stretches" in w]


def test_seams_trial_decided_where_the_cut_maps_coarse_level_hands_over(monkeypatch):
    """The noisy part of ``test_seams_not_tried_where_the_coarse_level_is_near_an_isometry``, with the noise bound
    switched off so that the cut is tried (3k coarse vertices: the cut mesh's boundary alone is more than half
    of 1.5k): the cut map pauses where its coarse level hands over, which does not lower the coarse iso mean
    (``seams.coarse_bound``), so its fine level is never polished; with the rule switched off too, the cut map
    was polished and lost, and the kept map is the same bit for bit."""
    from heatparam import options
    from heatparam.pipeline import seams
    from heatparam.refine import multilevel

    V, F = _noisy_cylinder_with_holes(0.2, 12_000)
    monkeypatch.setattr(multilevel, "COARSE_MIN", 3000)
    monkeypatch.setattr(seams, "noise_bound", lambda flat: None)
    r = parameterize(V, F, refine_multilevel=10_000)
    s = r.report["method"]["seams"]
    coarse = s["coarse_iso_means"]
    assert not s["used"] and "not polished on" in s["reason"]
    assert coarse["without"] - coarse["with"] < options.SEAM_MIN_GAIN * r.report["metrics"]["iso_mean"]
    monkeypatch.setattr(seams, "coarse_bound", lambda flat, cut: None)
    old = parameterize(V, F, refine_multilevel=10_000)
    so = old.report["method"]["seams"]
    assert not so["used"] and "coarse_iso_means" not in so
    assert so["iso_mean_with"] > so["iso_mean_without"] * (1 - options.SEAM_MIN_GAIN)
    assert np.array_equal(r.uv, old.uv) and r.report["metrics"] == old.report["metrics"]


def test_coarse_bound_needs_both_coarse_levels_and_a_cut_level_that_stopped():
    """The rule reads both maps' coarse levels: the cut map's must have stopped where its energy no longer fell
    (converged or stalled at the barrier) and the map without seams be bijective; otherwise no verdict."""
    from heatparam.pipeline import seams
    from heatparam.pipeline.report import Flat

    def flat(coarse, iso=1.056, bijective=True):
        ml = {"used": True, "coarse_iso_mean": coarse}
        return Flat(None, {"iso_mean": iso, "bijective": bijective}, {"refine": {"multilevel": ml}}, None, None, [])

    def cut(coarse, stop="converged", converged=True, iterations=0):
        ml = {"used": True, "coarse_iso_mean": coarse, "coarse_polish": {"converged": converged, "stop": stop}}
        return Flat(None, {"iso_mean": 1.3, "bijective": True},
                    {"refine": {"multilevel": ml, "polish": {"iterations": iterations}}}, None, None, [], lambda: None)

    assert seams.coarse_bound(flat(1.03), cut(1.02)) is not None  # gains 0.01 < 2% of 1.056
    assert seams.coarse_bound(flat(1.03), cut(1.035, "stalled at the barrier", False)) is not None
    assert seams.coarse_bound(flat(1.05), cut(1.02)) is None  # 0.03 ≥ 0.0211
    for c in (cut(1.02, "iteration cap", False), cut(1.02, iterations=3)):
        assert seams.coarse_bound(flat(1.03), c) is None
    assert seams.coarse_bound(flat(1.03, bijective=False), cut(1.02)) is None
