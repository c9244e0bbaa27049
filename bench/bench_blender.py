"""Blender's own unwrappers vs the heatparam extension's operator, in one Blender-as-a-module process (pip ``bpy``),
judged by the same checks: a markdown table.

Usage (a Python 3.11 venv with ``bpy`` and heatparam): ``python bench/bench_blender.py [name ...]`` (../shared/meshes
files, or ``cad``: a 40 mm block with a through hole and 3 mm fillets made with Blender's boolean and bevel: quads and
n-gons). Each method starts from the same freshly imported mesh (no seams, no UVs):

- Smart UV Project: ``bpy.ops.uv.smart_project()`` with its defaults (angle limit 66°, no margin), all faces, Edit mode;
- Minimum Stretch: ``bpy.ops.uv.unwrap(method='MINIMUM_STRETCH')`` (SLIM, Blender 4.3+), Angle Based:
  ``method='ANGLE_BASED'`` — both need seams to cut a closed mesh, so they run on open meshes only, as one island;
- heatparam: ``bpy.ops.uv.heatparam_unwrap(pack='texture')`` (charts within heatparam's automatic bound, packed
  into [0,1]²), with ``max_distortion=1.05``, and on open meshes ``pack='scale'`` (a disk in one bijective piece at
  true scale, as Minimum Stretch's one island; not in [0,1]²); its time includes starting the heatparam program
  (imports, about 2 s) and the OBJ round trip.

Columns: charts (pieces of the welded UV map); iso mean and p95 (``metrics.distortion``: area-weighted max(s1, 1/s2)
after one global area scale, flipped faces count as inf in p95); flips; overlapping triangle pairs (``atlas.overlap``,
exact); faces of zero UV area; UVs inside [0,1]² (to 1e-6: Smart UV Project leaves -1e-9); seconds (wall, the
operator call only). The UV map is read back from the mesh's active UV map (float32, as Blender stores it), face
corners welded per vertex where their UVs are equal, and judged on Blender's own triangulation of the faces.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import bpy  # noqa: I001 - Blender-as-a-module (pip bpy), Python 3.11
import numpy as np
from common import SHARED, machine

from heatparam import metrics
from heatparam.atlas.overlap import count_overlaps, uv_degenerate_faces
from heatparam.formats import load_mesh

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "integrations" / "blender"))
import heatparam_blender  # noqa: E402 - from integrations/blender

OPEN = {"camelhead.off", "beetle.off", "halftunnel.off", "bump-domain.obj"}
DEFAULT = ["cow.off", "3holes.off", "camelhead.off", "beetle.off", "cad"]


def _select(obj):
    bpy.ops.object.select_all(action="DESELECT")
    obj.select_set(True)
    bpy.context.view_layer.objects.active = obj
    return obj


def fresh(name: str, tmp: Path):
    """A new scene holding only the mesh, selected (``cad``: made here; a file: imported as OBJ)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    if name == "cad":
        return cad_part()
    import trimesh

    V, F = load_mesh(SHARED / name)
    path = tmp / "mesh.obj"
    trimesh.Trimesh(V, F, process=False).export(path)
    bpy.ops.wm.obj_import(filepath=str(path))
    return _select(bpy.context.selected_objects[0])


def cad_part(size: float = 40.0):
    """A block with a through hole and filleted edges (boolean and bevel), in a scene in millimetres."""
    u = bpy.context.scene.unit_settings
    u.system, u.length_unit, u.scale_length = "METRIC", "MILLIMETERS", 0.001
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
    return _select(part)


def in_edit_mode(op, **kw):
    """Run a Blender UV operator on all faces in Edit mode."""
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.mesh.select_all(action="SELECT")
    op(**kw)
    bpy.ops.object.mode_set(mode="OBJECT")


def judge(obj, seconds: float) -> dict:
    me = obj.data
    me.calc_loop_triangles()
    n = len(me.loop_triangles)
    tl = np.empty(3 * n, dtype=np.int64)
    me.loop_triangles.foreach_get("loops", tl)
    lv = np.empty(len(me.loops), dtype=np.int64)
    me.loops.foreach_get("vertex_index", lv)
    uv = np.empty(2 * len(me.loops), dtype=np.float32)
    me.uv_layers.active.data.foreach_get("uv", uv)
    co = np.empty(3 * len(me.vertices), dtype=np.float32)
    me.vertices.foreach_get("co", co)
    F, uv = lv[tl].reshape(-1, 3), uv.reshape(-1, 2).astype(np.float64)
    uvw, Fuv = metrics.weld_uv(F, uv[tl], np.arange(3 * n).reshape(-1, 3))
    d = metrics.distortion(co.reshape(-1, 3).astype(np.float64), F, uvw, Fuv)
    return {"charts": charts(uvw, Fuv), "iso_mean": d["iso_mean"], "iso_p95": d["iso_p95"], "flips": d["flips"],
            "overlaps": count_overlaps(uvw, Fuv), "collapsed": int(uv_degenerate_faces(uvw, Fuv).sum()),
            "in_square": bool(uv.min() >= -1e-6 and uv.max() <= 1.0 + 1e-6), "seconds": seconds}


def charts(uvw: np.ndarray, Fuv: np.ndarray) -> int:
    """Connected pieces of the welded UV map."""
    import scipy.sparse as sp

    t = np.tile(np.arange(len(Fuv)), 3)
    e = np.sort(np.concatenate([Fuv[:, [0, 1]], Fuv[:, [1, 2]], Fuv[:, [2, 0]]]), axis=1)
    _, inv = np.unique(e, axis=0, return_inverse=True)
    inc = sp.coo_matrix((np.ones(len(t)), (t, inv.ravel()))).tocsr()
    return int(sp.csgraph.connected_components(inc @ inc.T, directed=False)[0])


def methods(name: str) -> list[tuple[str, object]]:
    """(label, a call on the selected object) for the mesh ``name``."""
    out = [("Smart UV Project", lambda: in_edit_mode(bpy.ops.uv.smart_project))]
    if name in OPEN:
        methods_kw = bpy.ops.uv.unwrap.get_rna_type().properties["method"].enum_items.keys()
        out += [(f"Unwrap {m.replace('_', ' ').title()}", lambda m=m: in_edit_mode(bpy.ops.uv.unwrap, method=m))
                for m in ("MINIMUM_STRETCH", "ANGLE_BASED") if m in methods_kw]
    out += [("heatparam", lambda: bpy.ops.uv.heatparam_unwrap(pack="texture")),
            ("heatparam 1.05", lambda: bpy.ops.uv.heatparam_unwrap(pack="texture", max_distortion=1.05))]
    if name in OPEN:  # one bijective piece at true scale, as Minimum Stretch's one island
        out.append(("heatparam one piece", lambda: bpy.ops.uv.heatparam_unwrap(pack="scale")))
    return out


def fmt(name: str, method: str, r: dict) -> str:
    return (f"| {name} | {method} | {r['charts']} | {r['iso_mean']:.4f} | {r['iso_p95']:.4f} | {r['flips']} | "
            f"{r['overlaps']} | {r['collapsed']} | {'yes' if r['in_square'] else 'no'} | {r['seconds']:.2f} |")


def main(argv: list[str]) -> None:
    heatparam_blender.register()
    names = argv or DEFAULT
    print(f"Blender {bpy.app.version_string} (pip bpy); {machine()}")
    print("| mesh | method | charts | iso mean | iso p95 | flips | overlaps | collapsed | in [0,1]² | s |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for name in names:
            for label, call in methods(name):
                obj = fresh(name, Path(tmp))
                t = time.perf_counter()
                call()
                print(fmt(name, label, judge(obj, time.perf_counter() - t)), flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
