"""The View3D sidebar panel (tab "Atmosphere"): the sample's three control sets."""
import textwrap

import bpy

from . import baking
from .controls import ENABLED_BY, PROPERTIES_BY_SET, WITHOUT_EFFECT
from .scene.tables import wired_bake

# (operator idname, button text, icon); written in addon/ops.py.
OPERATORS = (
    ("ols.setup_scene", "Set Up Scene", 'WORLD'),
    ("ols.bake_luts", "Bake Tables", 'FILE_REFRESH'),
    ("ols.render", "Render", 'RENDER_STILL'),
    ("ols.measure_adaptation", "Measure Light Adaptation", 'RENDER_ANIMATION'),
    ("ols.pack_tables", "Pack Tables", 'PACKAGE'),
)


def operator_available(idname):
    """True when the operator ``idname`` ("ols.bake_luts") is registered."""
    module, name = idname.split(".", 1)
    return hasattr(bpy.types, f"{module.upper()}_OT_{name}")


def _runs(names):
    """Split ``names`` into consecutive runs of (in WITHOUT_EFFECT, [names])."""
    runs = []
    for name in names:
        inert = name in WITHOUT_EFFECT
        if runs and runs[-1][0] == inert:
            runs[-1][1].append(name)
        else:
            runs.append((inert, [name]))
    return runs


def draw_settings(layout, settings):
    """Draw the control-set drop-down and the controls of the selected set into ``layout``."""
    layout.prop(settings, "control_set", text="")
    names = PROPERTIES_BY_SET[settings.control_set]
    if any(name in WITHOUT_EFFECT for name in names):
        layout.label(text="Greyed controls have no effect yet (their tooltips say why)", icon='INFO')
    col = layout.column()
    col.use_property_split = True
    col.use_property_decorate = False
    for inert, run in _runs(names):
        sub = col.column()
        # Greyed but editable: values are kept with the scene for when the passes arrive.
        sub.active = not inert
        for name in run:
            if name in ENABLED_BY:
                row = sub.row()
                row.enabled = bool(ENABLED_BY[name](settings))
                row.prop(settings, name)
            else:
                sub.prop(settings, name)


def draw_operators(layout):
    col = layout.column(align=True)
    for idname, text, icon in OPERATORS:
        if operator_available(idname):
            col.operator(idname, text=text, icon=icon)
        else:
            row = col.row()
            row.enabled = False
            row.label(text=f"{text} (unavailable)", icon=icon)


def draw_table_problem(layout, scene):
    """A wired scene whose tables fail verification says so at the top, with the file and the
    fix: F12 cannot be stopped from the add-on, so the panel is where the user sees it."""
    problem = wired_bake.table_problem(scene)
    if problem is None:
        return
    box = layout.box()
    box.alert = True
    box.label(text="The tables fail verification:", icon='ERROR')
    for line in textwrap.wrap(problem, 48):
        box.label(text=line)
    box.label(text="Bake Tables repairs them before the next render")


def draw_bake_progress(layout, scene):
    """A bake running in the background: its stage and progress, and whether the scene shows the
    draft preview meanwhile."""
    bake = baking.latest()
    if bake is None:
        return
    box = layout.box()
    box.label(text=f"Baking tables: {bake.stage}", icon='SORTTIME')
    box.progress(factor=bake.fraction, text=f"{bake.fraction * 100:.0f}%")
    if baking.showing_preview(scene):
        box.label(text=f"Showing the {baking.preview_name(scene)} preview until they are done")
    if bake.render_after:
        box.label(text="The render starts when they are done")


class OLS_PT_atmosphere(bpy.types.Panel):
    """Outdoor Light Scattering: the sample's controls"""

    bl_idname = "OLS_PT_atmosphere"
    bl_label = "Outdoor Light Scattering"
    bl_space_type = 'VIEW_3D'
    bl_region_type = 'UI'
    bl_category = "Atmosphere"

    @classmethod
    def poll(cls, context):
        scene = getattr(context, "scene", None)
        return scene is not None and getattr(scene, "ols", None) is not None

    def draw(self, context):
        layout = self.layout
        draw_table_problem(layout, context.scene)
        draw_bake_progress(layout, context.scene)
        draw_settings(layout, context.scene.ols)
        layout.separator()
        draw_operators(layout)


CLASSES = (OLS_PT_atmosphere,)

