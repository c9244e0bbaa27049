"""The two operators: UV ▸ heatparam Unwrap (``uv.heatparam_unwrap``) and File ▸ Export ▸ heatparam flat pattern
(``export_mesh.heatparam_pattern``). Both send the mesh to heatparam (``runner``) through ``meshdata``; every
failure is one line in a Blender report and ``{'CANCELLED'}``, never a traceback.
"""


from pathlib import Path

import bpy
import numpy as np
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, StringProperty
from bpy_extras.io_utils import ExportHelper

from .knobs import KNOBS, knob_args, scene_units
from .meshdata import Loops, chart_borders, fit_unit_square, loop_uvs, marked_seams, polygon_edges, triangles, uv_seams
from .runner import RunError, Unwrap, find_command

PATTERN_SUFFIXES = (".dxf", ".svg", ".step", ".stp")
#: heatparam runs at most this often on one mesh: again when its charts cut through quads or n-gons, with their
#: borders moved onto polygon edges (``meshdata.chart_borders``) while that cuts fewer polygons each run; where it
#: stops doing so, the polygons still cut become charts of their own (``meshdata.polygon_edges``), one run more
CHART_PASSES = 5
_PACK_LABELS = {"scale": "charts at true scale in the scene's units", "texture": "UVs in [0,1]² (a texture map)"}


def knob_property(name: str, **override):
    """A Blender property for one of heatparam's options (``knobs.KNOBS``: its default, range, choices and help)."""
    k = KNOBS[name]._replace(**override)
    label = name.replace("_", " ").capitalize()
    if k.kind == "choice":
        items = [(c, c.capitalize(), _PACK_LABELS.get(c, c)) for c in k.choices]
        return EnumProperty(name=label, items=items, default=k.default, description=k.help)
    prop = FloatProperty if k.kind == "float" else IntProperty
    return prop(name=label, default=k.default, min=k.low, max=k.high, description=k.help)


def configured_command(context) -> str:
    """The heatparam program set in the extension's preferences ("" when unset or not installed as an extension)."""
    addon = context.preferences.addons.get(__package__)
    return addon.preferences.command if addon and addon.preferences else ""


class Status:
    """Progress in the status bar and the window's progress indicator while heatparam runs."""

    def __init__(self, context, total: int):
        self.wm, self.workspace, self.count, self.prefix = context.window_manager, context.workspace, 0, ""
        self.wm.progress_begin(0, max(total, 1))

    def object(self, name: str, index: int) -> None:
        self.prefix = name
        self.wm.progress_update(index)
        self.line("sending the mesh to heatparam")

    def line(self, text: str) -> None:
        if self.workspace is not None:
            self.workspace.status_text_set(f"{self.prefix}: {text}")
            if not bpy.app.background and bpy.context.window is not None:
                # the operator blocks Blender's event loop: redraw now, or the status bar shows only the last line
                bpy.ops.wm.redraw_timer(type="DRAW_WIN_SWAP", iterations=1)

    def end(self) -> None:
        self.wm.progress_end()
        if self.workspace is not None:
            self.workspace.status_text_set(None)


class Targets:
    """The meshes an operator works on and, in Edit mode, which faces: Object mode = every polygon of each selected
    mesh object (objects sharing one mesh unwrap it once); Edit mode = the selected faces of each edited mesh (read
    in Object mode, which Edit mode's mesh is synced to on the way)."""

    def __init__(self, context):
        self.editing = context.mode == "EDIT_MESH"
        objects = context.objects_in_mode_unique_data if self.editing else context.selected_objects
        seen, self.objects = set(), []
        for obj in objects:
            if obj.type == "MESH" and obj.data.name_full not in seen:
                seen.add(obj.data.name_full)
                self.objects.append(obj)

    def chosen(self, mesh) -> np.ndarray:
        """(P,) bool: the polygons to unwrap."""
        if not self.editing:
            return np.ones(len(mesh.polygons), dtype=bool)
        sel = np.zeros(len(mesh.polygons), dtype=bool)
        mesh.polygons.foreach_get("select", sel)
        return sel


def _units(context) -> tuple[str | None, float]:
    u = context.scene.unit_settings
    return scene_units(u.system, u.length_unit, u.scale_length)


def _pattern_mesh(obj, cut: bool, factor: float):
    """heatparam's triangles of a whole object (cut along its marked seams when ``cut``)."""
    mesh = obj.data
    seam = marked_seams(mesh) if cut else np.zeros(len(mesh.edges), dtype=bool)
    return triangles(mesh, Loops.of(mesh), np.ones(len(mesh.polygons), dtype=bool), seam,
                     np.array(obj.matrix_world, dtype=np.float64), factor)


def _fail(op, message: str) -> set:
    op.report({"ERROR"}, " ".join(str(message).split()) or "heatparam failed")
    return {"CANCELLED"}


class HEATPARAM_OT_unwrap(bpy.types.Operator):
    """Unwrap with heatparam: near-isometric, bijective charts within a distortion bound, into the active UV map"""

    bl_idname = "uv.heatparam_unwrap"
    bl_label = "heatparam Unwrap"
    bl_options = {"REGISTER", "UNDO"}

    pack: knob_property("pack", default="texture")
    max_distortion: knob_property("max_distortion")
    max_charts: knob_property("max_charts")
    padding: knob_property("padding")
    resolution: knob_property("resolution")
    seams: knob_property("seams")
    use_marked_seams: BoolProperty(name="Cut marked seams", default=True,
                                   description="edges marked as seams are cuts (chart borders)")
    mark_seams: BoolProperty(name="Mark seams", default=False,
                             description="mark the borders of heatparam's charts as seams")

    @classmethod
    def poll(cls, context):
        return context.mode in ("OBJECT", "EDIT_MESH")

    def execute(self, context):
        targets = Targets(context)
        if not targets.objects:
            return _fail(self, "select a mesh object (Object mode) or edit a mesh (Edit mode) to unwrap")
        if targets.editing:
            bpy.ops.object.mode_set(mode="OBJECT")
        status = Status(context, len(targets.objects))
        try:
            done = self._unwrap_all(context, targets, status)
        except RunError as exc:
            return _fail(self, exc)
        except Exception as exc:  # noqa: BLE001 - a Blender report, never a traceback
            return _fail(self, f"heatparam unwrap failed: {type(exc).__name__}: {exc}")
        finally:
            status.end()
            if targets.editing:
                bpy.ops.object.mode_set(mode="EDIT")
        if not done:
            return _fail(self, "no faces to unwrap: select faces in Edit mode")
        return {"FINISHED"}

    def _unwrap_all(self, context, targets: Targets, status: Status) -> int:
        units, factor = _units(context)
        values = {n: getattr(self, n) for n in ("pack", "max_distortion", "max_charts", "padding", "resolution",
                                                "seams")}
        job = Unwrap(find_command(configured_command(context)), knob_args(values), units, status.line)
        done = 0
        for i, obj in enumerate(targets.objects):
            status.object(obj.name, i)
            done += self._unwrap(obj, targets.chosen(obj.data), job, factor)
        for w in dict.fromkeys(job.warnings):
            self.report({"WARNING"}, w)
        if job.summary:
            self.report({"INFO"}, f"heatparam: {job.summary.split(': ', 1)[-1]}")
        return done

    def _unwrap(self, obj, chosen: np.ndarray, job: Unwrap, factor: float) -> int:
        """Unwrap one object's chosen faces into its active UV map; the number of faces unwrapped."""
        mesh = obj.data
        if not chosen.any():
            return 0
        loops = Loops.of(mesh)
        layer = mesh.uv_layers.active or mesh.uv_layers.new(name="UVMap")
        old = np.empty(2 * len(mesh.loops), dtype=np.float32)
        layer.data.foreach_get("uv", old)
        seam = marked_seams(mesh) if self.use_marked_seams else np.zeros(len(mesh.edges), dtype=bool)
        uv, split = self._flatten(obj, loops, chosen, seam, job, factor, old.reshape(-1, 2).astype(np.float64))
        layer.data.foreach_set("uv", uv.astype(np.float32).ravel())
        if split.any():
            faces = len(np.unique(loops.polygon[split]))
            self.report({"WARNING"}, f"{obj.name}: {faces} faces are still crossed by a chart border after "
                                     f"{CHART_PASSES} runs and cannot keep one UV per corner: triangulate them "
                                     "(Face ▸ Triangulate Faces) and unwrap again")
        if self.mark_seams:
            mesh.edges.foreach_set("use_seam", marked_seams(mesh) | uv_seams(loops, chosen[loops.polygon], uv,
                                                                             len(mesh.edges)))
        mesh.update()
        return int(chosen.sum())

    def _flatten(self, obj, loops: Loops, chosen: np.ndarray, seam: np.ndarray, job: Unwrap, factor: float,
                 old: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Every loop's UV (``old`` where not chosen) and the loops whose polygon a chart border still crosses."""
        matrix = np.array(obj.matrix_world, dtype=np.float64)
        best, cut_out = None, False  # best: (polygons cut, loop UVs, their split loops) of the run that cut fewest
        for _ in range(CHART_PASSES):
            tris = triangles(obj.data, loops, chosen, seam, matrix, factor)
            corner_uv = job.corner_uvs(tris.V, tris.F)
            if self.pack == "texture":  # the gutter at the square's border: half the one between charts, as heatparam's
                corner_uv = fit_unit_square(corner_uv, self.padding / (2.0 * self.resolution))
            uv, split = loop_uvs(tris, corner_uv, old)
            cut = np.unique(loops.polygon[split])
            progress = best is None or len(cut) < len(best[0])
            if progress:
                best = (cut, uv, split)
            if not len(best[0]) or (cut_out and not progress):
                break
            if progress:
                seam = seam | chart_borders(loops, tris, corner_uv, len(obj.data.edges))
            else:  # moving the borders no longer helps (a cut from a hole through a large n-gon, run after run)
                seam = seam | polygon_edges(loops, np.union1d(best[0], cut), len(obj.data.edges))
                cut_out = True
        return best[1], best[2]


class HEATPARAM_OT_export_pattern(bpy.types.Operator, ExportHelper):
    """Export the selected object's flat pattern (DXF, SVG or STEP by extension) at true scale in the scene's units"""

    bl_idname = "export_mesh.heatparam_pattern"
    bl_label = "Export heatparam flat pattern"
    bl_options = {"REGISTER"}

    filename_ext = ".dxf"
    filter_glob: StringProperty(default="*.dxf;*.svg;*.step;*.stp", options={"HIDDEN"})
    max_distortion: knob_property("max_distortion")
    max_charts: knob_property("max_charts")
    seams: knob_property("seams")
    use_marked_seams: BoolProperty(name="Cut marked seams", default=True,
                                   description="edges marked as seams are cuts (chart borders)")

    def check(self, context):
        return False  # keep the chosen extension: it picks the format (ExportHelper would force .dxf)

    def execute(self, context):
        path = Path(bpy.path.abspath(self.filepath))
        if path.suffix.lower() not in PATTERN_SUFFIXES:
            return _fail(self, f"{path.name}: choose a file name ending in .dxf, .svg or .step (the format)")
        obj = context.active_object if context.active_object in context.selected_objects else None
        meshes = [o for o in context.selected_objects if o.type == "MESH"]
        obj = obj if obj is not None and obj.type == "MESH" else (meshes[0] if len(meshes) == 1 else None)
        if obj is None:
            return _fail(self, "select one mesh object (or make it active) to export its flat pattern")
        editing = context.mode == "EDIT_MESH"
        if editing:
            bpy.ops.object.mode_set(mode="OBJECT")
        try:
            job = self._export(context, obj, path)
        except RunError as exc:
            return _fail(self, exc)
        except Exception as exc:  # noqa: BLE001 - a Blender report, never a traceback
            return _fail(self, f"heatparam export failed: {type(exc).__name__}: {exc}")
        finally:
            if editing:
                bpy.ops.object.mode_set(mode="EDIT")
        for w in dict.fromkeys(job.warnings):
            self.report({"WARNING"}, w)
        self.report({"INFO"}, job.summary or f"wrote {path}")
        return {"FINISHED"}

    def _export(self, context, obj, path: Path) -> Unwrap:
        if not len(obj.data.polygons):
            raise RunError(f"{obj.name} has no faces to flatten")
        units, factor = _units(context)
        status = Status(context, 1)
        try:
            status.object(obj.name, 0)
            tris = _pattern_mesh(obj, self.use_marked_seams, factor)
            values = {n: getattr(self, n) for n in ("max_distortion", "max_charts", "seams")}
            job = Unwrap(find_command(configured_command(context)), knob_args({"pack": "scale", **values}), units,
                         status.line)
            job.export(tris.V, tris.F, path)
        finally:
            status.end()
        return job


class HEATPARAM_AP_preferences(bpy.types.AddonPreferences):
    bl_idname = __package__

    command: StringProperty(name="heatparam program", subtype="FILE_PATH", default="",
                            description="path of the heatparam program; empty = heatparam on PATH, else the one "
                                        "installed in Blender's Python")

    def draw(self, context):
        self.layout.prop(self, "command")
        self.layout.label(text="Install it from heatparam's repository: pipx install . (or pip install .)")
