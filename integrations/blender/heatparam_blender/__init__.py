"""heatparam for Blender: UV ▸ heatparam Unwrap and File ▸ Export ▸ heatparam flat pattern.

heatparam itself runs as a separate program (``runner``): the ``heatparam`` command set in the preferences, on PATH,
or installed in Blender's Python. integrations/blender/README.md tells how to install both.
"""

import bpy

from .operators import HEATPARAM_AP_preferences, HEATPARAM_OT_export_pattern, HEATPARAM_OT_unwrap

CLASSES = (HEATPARAM_AP_preferences, HEATPARAM_OT_unwrap, HEATPARAM_OT_export_pattern)


def _unwrap_item(self, context):
    self.layout.operator(HEATPARAM_OT_unwrap.bl_idname, text="heatparam Unwrap")


def _export_item(self, context):
    self.layout.operator(HEATPARAM_OT_export_pattern.bl_idname, text="heatparam flat pattern (.dxf .svg .step)")


#: menu → its entry: the UV menus of Edit mode (3D view and UV editor), the Object menu (Object mode), File ▸ Export
MENUS = (("VIEW3D_MT_uv_map", _unwrap_item), ("IMAGE_MT_uvs", _unwrap_item), ("VIEW3D_MT_object", _unwrap_item),
         ("TOPBAR_MT_file_export", _export_item))


def register():
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    for menu, item in MENUS:
        getattr(bpy.types, menu).append(item)


def unregister():
    for menu, item in reversed(MENUS):
        getattr(bpy.types, menu).remove(item)
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
