"""The Blender extension (integrations/blender/heatparam_blender).

Its bpy-free modules (knobs, runner, meshdata) are tested everywhere; the operators only inside Blender-as-a-module
(pip ``bpy``, the ``blender`` extra: Python 3.11): those tests skip cleanly where ``bpy`` is absent.
"""

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

from heatparam import datasets, metrics, parameterize
from heatparam.atlas.overlap import count_overlaps, uv_degenerate_faces
from heatparam.formats import load_mesh
from heatparam.formats.units import UNITS
from heatparam.options import OPTIONS

EXT = Path(__file__).resolve().parents[1] / "integrations" / "blender"
MESHES = Path(__file__).resolve().parents[2] / "shared" / "meshes"


def _module(name: str):
    """A bpy-free module of the extension, loaded by path (the package's ``__init__`` imports bpy)."""
    path = EXT / "heatparam_blender" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(f"_heatparam_blender_{name}", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


knobs, runner, meshdata = _module("knobs"), _module("runner"), _module("meshdata")
HEATPARAM = [sys.executable, "-m", "heatparam"]


# ---------------------------------------------------------------------------------------------------------------
# without Blender
# ---------------------------------------------------------------------------------------------------------------
def test_knobs_mirror_the_options_table():
    table = {o.name: o for o in OPTIONS}
    for k in knobs.KNOBS.values():
        o = table[k.name]
        assert (k.default, k.choices, k.low, k.high, k.flag, k.help) == (o.default, o.choices, o.low, o.high,
                                                                         o.flag, o.short), k.name


def test_units_mirror_heatparam_units():
    assert {u: m * 1000.0 for u, m in knobs.METRES.items()} == pytest.approx({u: mm for u, (_, mm) in UNITS.items()})
    assert set(knobs.BLENDER_UNITS.values()) == set(UNITS)


@pytest.mark.parametrize("settings, expected", [
    (("METRIC", "MILLIMETERS", 0.001), ("mm", 1.0)),  # a part modelled in mm: 1 Blender unit = 1 mm
    (("METRIC", "MILLIMETERS", 1.0), ("mm", 1000.0)),  # Blender's default scale, shown in mm
    (("METRIC", "METERS", 1.0), ("m", 1.0)),
    (("METRIC", "CENTIMETERS", 0.01), ("cm", 1.0)),
    (("IMPERIAL", "INCHES", 0.0254), ("in", 1.0)),
    (("IMPERIAL", "FEET", 1.0), ("ft", 1.0 / 0.3048)),
    (("METRIC", "ADAPTIVE", 1.0), ("m", 1.0)),
    (("METRIC", "MICROMETERS", 1.0), ("mm", 1000.0)),
    (("NONE", "ADAPTIVE", 1.0), (None, 1.0)),
])
def test_scene_units(settings, expected):
    unit, factor = knobs.scene_units(*settings)
    assert unit == expected[0] and factor == pytest.approx(expected[1])


def test_knob_args_are_cli_flags():
    assert knobs.knob_args({"pack": "texture", "max_distortion": 1.05, "resolution": 512}) == [
        "--pack", "texture", "--max-distortion", "1.05", "--resolution", "512"]


def test_runner_gives_parameterize_corner_uvs():
    """The command's OBJ, read back, is the API's map corner for corner (the same options)."""
    s = datasets.cylinder_patch(h=0.1)
    job = runner.Unwrap(HEATPARAM, knobs.knob_args({"seams": "holes"}), "mm")
    got = job.corner_uvs(s.V, s.F)
    res = parameterize(s.V, s.F, seams="holes", unit_name="mm")
    assert got.shape == (len(s.F), 3, 2)
    np.testing.assert_allclose(got, res.uv[res.Fuv], rtol=0, atol=1e-9 * np.ptp(res.uv))
    assert job.summary.startswith("wrote ") and "0 flipped" in job.summary


def test_runner_errors_are_one_line():
    s = datasets.cylinder_patch(h=0.2)
    with pytest.raises(runner.RunError, match=r"^--max-distortion must be 0 \(automatic\) or more than 1"):
        runner.Unwrap(HEATPARAM, ["--max-distortion", "0.5"], None).corner_uvs(s.V, s.F)
    with pytest.raises(runner.RunError, match="not an executable file.*pipx install"):
        runner.find_command("/nonexistent/heatparam")
    with pytest.raises(runner.RunError, match="cannot run"):
        runner.Unwrap(["/nonexistent/heatparam"], [], None).corner_uvs(s.V, s.F)


def _loops(faces: list[list[int]]):
    """meshdata.Loops of polygons given as vertex lists (edges numbered in order of first use)."""
    edges: dict[tuple[int, int], int] = {}
    vertex, edge, nxt, poly = [], [], [], []
    for p, f in enumerate(faces):
        start = len(vertex)
        for k, v in enumerate(f):
            w = f[(k + 1) % len(f)]
            vertex.append(v)
            edge.append(edges.setdefault((min(v, w), max(v, w)), len(edges)))
            nxt.append(start + (k + 1) % len(f))
            poly.append(p)
    return meshdata.Loops(*(np.array(x, dtype=np.int64) for x in (vertex, edge, nxt, poly))), edges


@pytest.mark.parametrize("marked, vertices", [
    ([], 7),  # uncut fan
    ([(0, 1)], 8),  # one spoke: a slit, its border end (1) splits, the centre does not
    ([(0, 1), (0, 4)], 10),  # two spokes cut the fan in two: the centre and both ends split
])
def test_marked_seams_split_vertices(marked, vertices):
    loops, edges = _loops([[0, i, i % 6 + 1] for i in range(1, 7)])
    seam = np.zeros(len(edges), dtype=bool)
    seam[[edges[e] for e in marked]] = True
    vert = meshdata.corner_vertices(loops, np.ones(len(loops.vertex), dtype=bool), seam)
    assert vert.max() + 1 == vertices
    for v in range(7):  # every cut vertex is a copy of one input vertex
        assert len(set(loops.vertex[vert == v])) <= 1


def test_polygon_edges_cut_the_polygons_out():
    """The edges of the chosen polygons, theirs alone: a quad between two triangles, cut out on all four sides."""
    loops, edges = _loops([[0, 1, 2], [1, 3, 4, 2], [3, 5, 4]])
    out = meshdata.polygon_edges(loops, np.array([1]), len(edges))
    assert {e for e, i in edges.items() if out[i]} == {(1, 3), (3, 4), (2, 4), (1, 2)}


def test_fit_unit_square_keeps_shape():
    uv = np.random.default_rng(0).normal(size=(10, 3, 2)) * [3.0, 1.0]
    fit = meshdata.fit_unit_square(uv, 0.01)
    assert fit.min() == pytest.approx(0.01) and fit.max() <= 0.99 + 1e-12
    scale = np.ptp(fit) / np.ptp(uv)  # one uniform scale and a shift
    np.testing.assert_allclose(fit - fit[0, 0], (uv - uv[0, 0]) * scale, atol=1e-12)
    inside = np.full((2, 3, 2), 0.5)
    assert meshdata.fit_unit_square(inside, 0.01) is inside


# ---------------------------------------------------------------------------------------------------------------
# inside Blender (pip bpy)
# ---------------------------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def bl():
    bpy = pytest.importorskip("bpy")
    sys.path.insert(0, str(EXT))
    import heatparam_blender

    heatparam_blender.register()
    yield bpy
    heatparam_blender.unregister()
    sys.path.remove(str(EXT))


@pytest.fixture
def scene(bl):
    bl.ops.wm.read_factory_settings(use_empty=True)
    return bl.context.scene


def _select(bpy, obj):
    bpy.ops.object.select_all(action="DESELECT")
    obj.select_set(True)
    bpy.context.view_layer.objects.active = obj
    return obj


def _import(bpy, tmp_path, V, F):
    import trimesh

    path = tmp_path / "mesh.obj"
    trimesh.Trimesh(V, F, process=False).export(path)
    bpy.ops.wm.obj_import(filepath=str(path))
    return _select(bpy, bpy.context.selected_objects[0])


def _cad_part(bpy, size=40.0):
    """A CAD-like part: a block with a through hole and filleted edges (Blender's boolean and bevel: quads and
    n-gons)."""
    bpy.ops.mesh.primitive_cube_add(size=size)
    part = bpy.context.active_object
    bpy.ops.mesh.primitive_cylinder_add(radius=size / 5, depth=size * 1.5, vertices=32)
    tool = bpy.context.active_object
    hole = part.modifiers.new("hole", "BOOLEAN")
    hole.object, hole.operation = tool, "DIFFERENCE"
    fillet = part.modifiers.new("fillet", "BEVEL")
    fillet.width, fillet.segments = size * 0.075, 3
    bpy.context.view_layer.objects.active = part
    bpy.ops.object.modifier_apply(modifier="hole")
    bpy.ops.object.modifier_apply(modifier="fillet")
    bpy.data.objects.remove(tool)
    return _select(bpy, part)


def _corners(obj):
    """Blender's triangles of the mesh: vertex ids (t,3), loop ids (t,3), the active UV map per loop (L,2),
    vertex positions (n,3)."""
    me = obj.data
    me.calc_loop_triangles()
    tl = np.array([t.loops[:] for t in me.loop_triangles], dtype=np.int64)
    lv = np.array([lp.vertex_index for lp in me.loops], dtype=np.int64)
    uv = np.array([d.uv[:] for d in me.uv_layers.active.data], dtype=np.float64)
    co = np.array([v.co[:] for v in me.vertices], dtype=np.float64)
    return lv[tl], tl, uv, co


def _judge(obj) -> dict:
    """The active UV map, its face corners welded per vertex where their UVs are equal, judged by heatparam's
    metrics."""
    F, tl, uv, co = _corners(obj)
    uvw, Fuv = metrics.weld_uv(F, uv[tl].reshape(-1, 2), np.arange(tl.size).reshape(-1, 3))
    d = metrics.distortion(co, F, uvw, Fuv)
    return {"flips": d["flips"], "iso_mean": d["iso_mean"], "overlaps": count_overlaps(uvw, Fuv),
            "collapsed": int(uv_degenerate_faces(uvw, Fuv).sum()), "lo": uv.min(), "hi": uv.max(),
            "charts": _charts(F, uvw, Fuv)}


def _charts(F, uvw, Fuv) -> int:
    """Connected pieces of the welded UV map (triangles sharing a welded UV edge)."""
    import scipy.sparse as sp

    e = np.sort(np.concatenate([Fuv[:, [0, 1]], Fuv[:, [1, 2]], Fuv[:, [2, 0]]]), axis=1)
    t = np.tile(np.arange(len(F)), 3)
    _, inv = np.unique(e, axis=0, return_inverse=True)
    inc = sp.coo_matrix((np.ones(len(t)), (t, inv.ravel()))).tocsr()
    return sp.csgraph.connected_components(inc @ inc.T, directed=False)[0]


def test_registered(bl):
    op = bl.ops.uv.heatparam_unwrap.get_rna_type()
    assert {"pack", "max_distortion", "padding", "resolution", "seams", "mark_seams"} <= set(op.properties.keys())
    assert "filepath" in bl.ops.export_mesh.heatparam_pattern.get_rna_type().properties.keys()


@pytest.mark.parametrize("name", ["cow.off", "3holes.off", "cad"])
def test_unwrap_acceptance(bl, scene, tmp_path, name):
    """Closed, genus 3, a CAD part: FINISHED, bijective, within the bound, in [0,1]²."""
    if name == "cad":
        obj = _cad_part(bl)
    else:
        obj = _import(bl, tmp_path, *load_mesh(MESHES / name))
        assert not obj.data.uv_layers  # the operator creates the UV map
    assert bl.ops.uv.heatparam_unwrap(pack="texture", max_distortion=1.05) == {"FINISHED"}
    r = _judge(obj)
    assert (r["flips"], r["overlaps"], r["collapsed"]) == (0, 0, 0), r
    assert r["iso_mean"] <= 1.05, r
    assert 0.0 <= r["lo"] and r["hi"] <= 1.0, r


def _tube(bpy, vertices=16):
    bpy.ops.mesh.primitive_cylinder_add(vertices=vertices, radius=1.0, depth=2.0, end_fill_type="NOTHING")
    return _select(bpy, bpy.context.active_object)


def _uv_cut_edges(obj) -> set:
    """Edges between two faces whose sides have different UVs at an end."""
    me = obj.data
    uv = {}
    for p in me.polygons:
        for li in p.loop_indices:
            uv[(p.index, me.loops[li].vertex_index)] = tuple(me.uv_layers.active.data[li].uv)
    sides: dict[int, list[int]] = {}
    for p in me.polygons:
        for ek in p.edge_keys:
            sides.setdefault(me.edges[[e.key for e in me.edges].index(ek)].index, []).append(p.index)
    cut = set()
    for e, ps in sides.items():
        if len(ps) == 2 and any(uv[(ps[0], v)] != uv[(ps[1], v)] for v in me.edges[e].vertices):
            cut.add(e)
    return cut


def test_marked_seam_line_cuts_a_cylinder_into_one_chart(bl, scene):
    obj = _tube(bl)
    me = obj.data
    line = {e.index for e in me.edges
            if all(me.vertices[v].co.x > 0.99 and abs(me.vertices[v].co.y) < 1e-6 for v in e.vertices)}
    assert len(line) == 1
    for e in line:
        me.edges[e].use_seam = True
    assert bl.ops.uv.heatparam_unwrap(pack="scale", seams="none") == {"FINISHED"}
    r = _judge(obj)
    assert r["charts"] == 1 and r["flips"] == 0 and r["overlaps"] == 0
    assert r["iso_mean"] < 1.001  # a cut cylinder is developable: true scale
    assert _uv_cut_edges(obj) == line


def test_marked_seams_ignored_on_request(bl, scene):
    obj = _tube(bl)
    for e in obj.data.edges:
        e.use_seam = True
    assert bl.ops.uv.heatparam_unwrap(pack="scale", seams="none", use_marked_seams=False) == {"FINISHED"}
    assert _uv_cut_edges(obj) == set()  # an annulus, uncut (seams none)


def test_ngon_mesh_and_marked_chart_borders(bl, scene):
    """A closed cylinder with 24-gon caps: the n-gons keep their loops (no triangulation), each drawn whole, and
    ``mark_seams`` marks exactly the charts' borders."""
    bl.ops.mesh.primitive_cylinder_add(vertices=24, radius=10.0, depth=30.0, end_fill_type="NGON")
    obj = _select(bl, bl.context.active_object)
    polygons = len(obj.data.polygons)
    assert bl.ops.uv.heatparam_unwrap(pack="texture", max_distortion=1.05, mark_seams=True) == {"FINISHED"}
    assert len(obj.data.polygons) == polygons and max(p.loop_total for p in obj.data.polygons) == 24
    r = _judge(obj)
    assert (r["flips"], r["overlaps"], r["collapsed"]) == (0, 0, 0) and r["iso_mean"] <= 1.05, r
    marked = {e.index for e in obj.data.edges if e.use_seam}
    assert marked and marked == _uv_cut_edges(obj)


def test_edit_mode_unwraps_the_selected_faces(bl, scene):
    obj = _tube(bl)
    before = np.array([d.uv[:] for d in obj.data.uv_layers.active.data])
    keep = {p.index for p in obj.data.polygons if p.center.x < 0}
    bl.ops.object.mode_set(mode="EDIT")
    bl.ops.mesh.select_all(action="DESELECT")
    bl.ops.object.mode_set(mode="OBJECT")
    for p in obj.data.polygons:
        p.select = p.index not in keep
    bl.ops.object.mode_set(mode="EDIT")
    assert bl.ops.uv.heatparam_unwrap(pack="texture") == {"FINISHED"}
    assert bl.context.mode == "EDIT_MESH"
    bl.ops.object.mode_set(mode="OBJECT")
    after = np.array([d.uv[:] for d in obj.data.uv_layers.active.data])
    for p in obj.data.polygons:
        changed = not np.array_equal(before[list(p.loop_indices)], after[list(p.loop_indices)])
        assert changed == (p.index not in keep), p.index


def test_errors_are_reports(bl, scene, monkeypatch):
    import heatparam_blender.operators as ops

    with pytest.raises(RuntimeError, match="select a mesh object"):
        bl.ops.uv.heatparam_unwrap()
    obj = _tube(bl)
    before = [d.uv[:] for d in obj.data.uv_layers.active.data]
    with pytest.raises(RuntimeError, match=r"--max-distortion must be 0 \(automatic\) or more than 1") as info:
        bl.ops.uv.heatparam_unwrap(max_distortion=0.5)
    assert "\n" not in str(info.value).strip()
    monkeypatch.setattr(ops, "configured_command", lambda context: "/nonexistent/heatparam")
    with pytest.raises(RuntimeError, match="not an executable file"):
        bl.ops.uv.heatparam_unwrap()
    assert [d.uv[:] for d in obj.data.uv_layers.active.data] == before


def test_undo_restores_uvs(bl, scene):
    assert "UNDO" in bl.ops.uv.heatparam_unwrap.bl_options
    obj = _tube(bl)
    before = [d.uv[:] for d in obj.data.uv_layers.active.data]
    bl.ops.ed.undo_push(message="before heatparam")
    assert bl.ops.uv.heatparam_unwrap(pack="texture") == {"FINISHED"}
    assert [d.uv[:] for d in bl.context.active_object.data.uv_layers.active.data] != before
    # the UI pushes an undo step after an operator with UNDO in its options; an operator called from a script in
    # background mode does not, so the step is pushed here as the UI would
    bl.ops.ed.undo_push(message="heatparam Unwrap")
    assert bl.ops.ed.undo() == {"FINISHED"}
    obj = bl.context.active_object
    assert [d.uv[:] for d in obj.data.uv_layers.active.data] == before


def _dxf_area(path, layer) -> float:
    import ezdxf

    total = 0.0
    for pl in ezdxf.readfile(path).modelspace().query(f'LWPOLYLINE[layer=="{layer}"]'):
        P = np.array([p[:2] for p in pl.get_points("xy")])
        total += 0.5 * abs(np.dot(P[:, 0], np.roll(P[:, 1], -1)) - np.dot(P[:, 1], np.roll(P[:, 0], -1)))
    return total


@pytest.mark.parametrize("scale_length, size", [(0.001, 40.0), (1.0, 0.04)])
def test_export_dxf_in_scene_units(bl, scene, tmp_path, scale_length, size):
    """A 40 mm part, modelled in mm (1 unit = 1 mm) or in metres shown in mm: a DXF in mm, its OUTLINE layer the
    charts' outlines, their area (less the holes') the part's."""
    import ezdxf

    units = scene.unit_settings
    units.system, units.length_unit, units.scale_length = "METRIC", "MILLIMETERS", scale_length
    obj = _cad_part(bl, size)
    F, _, _, co = _corners(obj)
    area_mm2 = 0.5 * np.linalg.norm(np.cross(co[F[:, 1]] - co[F[:, 0]], co[F[:, 2]] - co[F[:, 0]]), axis=1).sum()
    area_mm2 *= (scale_length * 1000.0) ** 2
    path = tmp_path / "part.dxf"
    assert bl.ops.export_mesh.heatparam_pattern(filepath=str(path)) == {"FINISHED"}
    doc = ezdxf.readfile(path)
    assert doc.header["$INSUNITS"] == 4  # millimetres
    assert len(doc.modelspace().query('LWPOLYLINE[layer=="OUTLINE"]')) >= 1
    flat = _dxf_area(path, "OUTLINE") - _dxf_area(path, "HOLES")
    assert flat == pytest.approx(area_mm2, rel=0.05)


def test_export_refuses_other_formats(bl, scene, tmp_path):
    _tube(bl)
    with pytest.raises(RuntimeError, match=r"choose a file name ending in \.dxf, \.svg or \.step"):
        bl.ops.export_mesh.heatparam_pattern(filepath=str(tmp_path / "x.obj"))
    assert not (tmp_path / "x.obj").exists()


def _build(out: Path) -> Path:
    spec = importlib.util.spec_from_file_location("_heatparam_blender_build", EXT / "build.py")
    build = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(build)
    return build.build(out)


def test_build_zip(tmp_path):
    """The archive Blender installs: the manifest and the modules at its root, the manifest's required fields."""
    import zipfile

    tomllib = pytest.importorskip("tomllib")  # Python 3.11+
    zip_path = _build(tmp_path)
    names = zipfile.ZipFile(zip_path).namelist()
    assert names[0] == "blender_manifest.toml" and {"__init__.py", "operators.py", "runner.py"} <= set(names)
    assert not any("__pycache__" in n or n.endswith(".pyc") for n in names)
    m = tomllib.loads(zipfile.ZipFile(zip_path).read("blender_manifest.toml").decode())
    assert m["schema_version"] == "1.0.0" and m["type"] == "add-on" and m["blender_version_min"] >= "4.2.0"
    assert zip_path.name == f"{m['id']}-{m['version']}.zip" and m["license"] == ["SPDX:MIT"]
    assert len(m["tagline"]) <= 64 and m["tagline"][-1].isalnum()


INSTALL = """
import sys, bpy
zip_path, command = sys.argv[1:3]
assert bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default",
                                                enable_on_install=True) == {"FINISHED"}
bpy.context.preferences.addons["bl_ext.user_default.heatparam_blender"].preferences.command = command
bpy.ops.object.select_all(action="DESELECT")
bpy.ops.mesh.primitive_cylinder_add(vertices=12, end_fill_type="NOTHING")
print(bpy.ops.uv.heatparam_unwrap(pack="texture"))
"""


def test_zip_installs_as_an_extension(tmp_path):
    """Blender's own installer takes the archive (it checks the manifest); the installed extension runs the heatparam
    program set in its preferences. In a fresh process whose user folder is tmp_path."""
    import os
    import subprocess

    pytest.importorskip("bpy")
    command = Path(sys.executable).with_name("heatparam")
    if not command.is_file():
        pytest.skip("no heatparam program beside this Python")
    env = {**os.environ, "HOME": str(tmp_path), "PATH": "/usr/bin:/bin"}  # heatparam found through the preferences
    out = subprocess.run([sys.executable, "-c", INSTALL, str(_build(tmp_path / "dist")), str(command)], env=env,
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "{'FINISHED'}" in out.stdout
    assert list((tmp_path / ".config" / "blender").glob("*/extensions/user_default/heatparam_blender/operators.py"))
