"""The seams stage's cut mesh (``pipeline.seams``)."""

from __future__ import annotations

import numpy as np
import pytest

from heatparam import datasets, parameterize
from heatparam.formats import load_mesh

from conftest import shared_mesh


def _cap():
    """A strongly curved cap (sphere radius 1.5) with two eye holes and a mouth slot, ~1.2k vertices."""
    s = datasets.curved_cap_with_holes(sphere_radius=1.5, h=0.05)
    return s.V, s.F


def _halftunnel():
    return load_mesh(shared_mesh("halftunnel.off"))


@pytest.mark.parametrize("case,kw,why", [(_halftunnel, {}, "the surface is cut open along seams"),
                                         (_cap, {"seams": "holes"}, "the conformal layout is bijective and within")],
                         ids=["halftunnel", "cap"])
def test_cut_mesh_skips_the_heat_stage_with_the_same_map(case, kw, why):
    V, F = case()
    a = parameterize(V, F, **kw)
    b = parameterize(V, F, mds_start="always", **kw)
    assert a.seamed and b.seamed
    assert a.report["method"]["geodesics"].startswith(f"skipped: {why}")
    assert not b.report["method"]["geodesics"].startswith("skipped")
    assert np.array_equal(a.uv, b.uv) and np.array_equal(a.Fuv, b.Fuv)


def test_a_folded_border_ear_leaves_the_cut_mesh_its_projection_start():
    """A projection that folds one border ear under its neighbour used to be refused as the cut mesh's start (a
    flipped face whose corners the repair cannot move): the refinement then started from Tutte."""
    from conftest import with_ear

    s = datasets.cylinder_with_holes()
    V, F, _ = with_ear(s.V, s.F, s.uv_true, fold=True)
    r = parameterize(V, F, seams="holes")
    rep = r.report["method"]["seams"]["projection_reopened"]
    assert "reason" not in rep and rep["unflipped"]["repaired"] and rep["unflipped"]["flips"] == 1
    assert r.report["method"]["refine"]["start"]["layout"] != "tutte"
    assert r.report["metrics"]["bijective"]


def test_a_spiked_border_gives_the_cut_mesh_its_smoothed_conformal_start(monkeypatch):
    """Outliers on the border fold the cut mesh's conformal layout beyond repair, and a cylinder rolled past a half
    turn folds its projection: the cut map starts from the conformal layout of the smoothed cut mesh, whose
    crossing slits would be reopened as the conformal layout's are, instead of Tutte's embedding."""
    import heatparam.pipeline as pl
    import heatparam.pipeline.seams as seams
    from heatparam.mesh.topology import boundary_loops

    s = datasets.cylinder_with_holes(angle=4.5, h=0.06)
    V = s.V.copy()
    for v in max(boundary_loops(s.F), key=len)[::29][:8]:  # outliers on the outer border, 6 edges out
        radial = V[v] * [1.0, 0.0, 1.0]
        V[v] += 6 * 0.06 * radial / np.linalg.norm(radial)
    repairs = []
    flatten = pl.flatten

    def spy(surface, *args, **kw):
        repairs.append(kw.get("repair"))
        return flatten(surface, *args, **kw)

    monkeypatch.setattr(pl, "flatten", spy)  # the seams stage is handed pipeline.flatten
    r = parameterize(V, s.F, seams="holes")
    start = r.report["method"]["refine"]["start"]
    assert "flipped faces" in r.report["method"]["seams"]["conformal_reopened"]["reason"]
    assert start["layout"] == "conformal_smoothed" and start["energy"]["conformal_smoothed"] < 2.0
    assert r.seamed and r.report["metrics"]["bijective"]
    assert [rp.func for rp in repairs if rp is not None] == [seams._reopened]


def _noisy_cap():
    """The cap of :func:`_cap` with depth noise (0.3 × the edge along z, as a range image's): its projection beats
    its conformal layout as a start."""
    s = datasets.curved_cap_with_holes(sphere_radius=1.5, h=0.05)
    V = s.V.copy()
    V[:, 2] += 0.3 * 0.05 * np.random.default_rng(0).standard_normal(len(V))
    return V, s.F


def test_the_cut_mesh_computes_no_conformal_layout_where_the_projection_started_the_map_without_seams(monkeypatch):
    """Where the map without seams started from the projection (lower in energy than the conformal layout) and
    the cut mesh's projection, slits reopened, is bijective, the cut mesh's conformal layout is not computed: the
    same map as with it (it lost again), the reason in the report; where the conformal layout started the map
    without seams, the cut mesh's is computed."""
    from heatparam.pipeline.surface import Surface

    V, F = _noisy_cap()
    a = parameterize(V, F, seams="holes", mds_start="never")
    method = a.report["method"]
    assert method["without_seams"]["refine"]["start"]["layout"] == "projection"
    assert "not computed: the map without seams started from the projection" in \
        method["seams"]["conformal_reopened"]["reason"]
    assert method["refine"]["start"]["layout"] == "projection_reopened"
    assert "conformal" not in method["refine"]["start"]["energy"]

    monkeypatch.setattr(Surface, "conformal_skipped", property(lambda s: None, lambda s, v: None), raising=False)
    b = parameterize(V, F, seams="holes", mds_start="never")
    start = b.report["method"]["refine"]["start"]
    assert start["layout"] == "projection_reopened" and start["energy"]["conformal"] > start["energy"][
        "projection_reopened"]
    assert np.array_equal(a.uv, b.uv) and np.array_equal(a.Fuv, b.Fuv)
    monkeypatch.undo()

    V, F = _cap()
    c = parameterize(V, F, seams="holes", mds_start="never")
    assert c.report["method"]["without_seams"]["refine"]["start"]["layout"] == "conformal"
    assert "conformal" in c.report["method"]["refine"]["start"]["energy"]
