"""The add-on's controls as one PropertyGroup on the Scene (``scene.ols``), made from the
controls registry (addon/controls.py), and what a change of each does at once (its update).

The registry declares every control; this module turns each declaration into a bpy property and
maps its ``Change`` to the callback below. How the render reads them (clamped, capped, mapped to
table parameters) is settings.py.
"""
import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, FloatVectorProperty, IntProperty

from ..lut_gen.clouds.presets import CLOUD_PRESETS
from ..lut_gen.model.air_presets import AIR_PRESETS, FOG_PRESETS
from . import baking
from .controls import CONTROLS, Change, Control
from .scene import clouds, names
from .scene.setup import compositor, wiring
from .scene.tables import wired_bake
from .settings import apply_air_preset, validated_params

REBAKE_DELAY_S = 0.75     # wait for a slider drag to settle before re-baking


def _rebake_soon(settings, context):
    """Changing the media re-bakes the tables in the background and swaps them into a wired
    scene (interactive sessions only; scripts call bpy.ops.ols.bake_luts themselves). Under the
    analytic model the groups are rebuilt at once instead, in scripts too: nothing to bake."""
    if context.scene is not None and wiring.wants_analytic(context.scene) and wired_bake.is_analytic(context.scene):
        wiring.use_model(context.scene)
        return
    if bpy.app.background or context.scene is None or not context.scene.get(names.WIRED_KEY):
        return
    if bpy.app.timers.is_registered(_start_rebake):
        bpy.app.timers.unregister(_start_rebake)
    bpy.app.timers.register(_start_rebake, first_interval=REBAKE_DELAY_S)


def _sync_compositor(settings, context):
    """Compositor inputs follow the settings (drivers on a compositor tree do not reach
    renders). Steps, modes and cascade settings rebuild the light-shaft groups, but not here:
    the depsgraph update that follows each change in the UI, a still's render_pre and each
    animation frame's frame_change_pre (which comes before the frame's compositor depsgraph)
    rebuild them once. Rebuilt in the callbacks, a script setting ten controls would rebuild
    them ten times, ~1 s each."""
    if context.scene is not None:
        compositor.sync_settings(context.scene)


def _sync_clouds(settings, context):
    """The cloud map follows the seed (0.36 s to make), the shadow layer and the compositor's
    cloud veil the on/off switch."""
    if context.scene is not None:
        clouds.sync(context.scene)
        compositor.sync_settings(context.scene)


def _switch_model(settings, context):
    """A wired scene follows the Atmosphere Model at once: the analytic groups, or the tables
    from the cache (switching back and forth never re-bakes). Tables not baked yet bake in the
    background in the UI; a script bakes them with bpy.ops.ols.bake_luts, and a render settles
    first (baking.settle), so no frame renders the model it was not asked for."""
    scene = context.scene
    if scene is None or not scene.get(names.WIRED_KEY):
        return
    if settings.atmosphere_model == "ANALYTIC":
        wiring.use_model(scene)
        return
    if not wired_bake.is_analytic(scene):
        return                          # on the tables already
    resolution = scene.get(names.RESOLUTION_KEY, "default")
    try:
        params = validated_params(settings)
    except ValueError as exc:
        print(f"Outdoor Light Scattering: no tables for these settings: {exc}")
        return
    if baking.is_baked(params, resolution):
        wiring.use_model(scene, baking.bake_directory(params, resolution))
    elif not bpy.app.background:
        baking.invoke_bake_in_window(resolution)


def _apply_air_preset(settings, context):
    key = settings.air_preset.lower().replace("_", "-")
    if key in AIR_PRESETS or key in FOG_PRESETS:
        apply_air_preset(settings, key)     # the controls' own updates re-bake the tables


def _apply_cloud_preset(settings, context):
    key = settings.cloud_preset.lower().replace("_", "-")
    for name, value in CLOUD_PRESETS.get(key, {}).items():
        setattr(settings, f"cloud_{name}", value)


def _capture_day_range(settings, context):
    """Animate Sun spreads the day over the frame range it was turned on with, not over
    whatever range a later (chunked) render sets."""
    if settings.animate_sun and context.scene is not None:
        settings.day_start_frame, settings.day_end_frame = context.scene.frame_start, context.scene.frame_end


def _start_rebake():
    baking.invoke_bake_in_window(bpy.context.scene.get(names.RESOLUTION_KEY, "default"))
    return None


UPDATES = {
    Change.REBAKE: _rebake_soon,
    Change.COMPOSITOR: _sync_compositor,
    Change.CLOUD_MAP: _sync_clouds,
    Change.MODEL: _switch_model,
    Change.DAY_RANGE: _capture_day_range,
    Change.DRIVERS: None,           # the drivers Set Up Scene made read the control
    Change.NOTHING: None,
}
PRESET_UPDATES = {"air_preset": _apply_air_preset, "cloud_preset": _apply_cloud_preset}


def _update(control: Control):
    return PRESET_UPDATES[control.name] if control.change is Change.PRESET else UPDATES[control.change]


def bpy_property(control: Control):
    """The bpy property that stores ``control``: its kind, label, tooltip, default, range, unit."""
    options = dict(name=control.label, description=control.tooltip)
    update = _update(control)
    if update is not None:
        options["update"] = update
    if control.kind == "bool":
        return BoolProperty(default=control.default, **options)
    if control.kind == "enum":
        return EnumProperty(items=control.items, default=control.default, **options)
    if control.range is not None:
        options["min"], options["max"] = control.range
    if control.soft_max is not None:
        options["soft_max"] = control.soft_max
    if control.kind == "int":
        return IntProperty(default=control.default, **options)
    if control.unit == "m":
        options["unit"] = "LENGTH"
    if control.subtype:
        options["subtype"] = control.subtype
    if control.precision is not None:
        options["precision"] = control.precision
    if control.step is not None:
        options["step"] = control.step
    if control.kind == "float":
        return FloatProperty(default=control.default, **options)
    if control.kind == "color":
        options["subtype"] = "COLOR"
    return FloatVectorProperty(size=len(control.default), default=control.default, **options)


OLSSettings = type("OLSSettings", (bpy.types.PropertyGroup,), {
    "__doc__": "Outdoor Light Scattering settings (the sample's GUI), stored on the scene.",
    "__annotations__": {control.name: bpy_property(control) for control in CONTROLS},
})

CLASSES = (OLSSettings,)
