"""Blender-side add-on code (settings, operators, handlers, UI) for Outdoor Light Scattering.

``register()`` registers, in order: the settings PropertyGroup and ``Scene.ols`` (props), the
operators (ops), the app handlers (handlers), then the sidebar panel (ui). ``unregister()``
undoes the same steps in reverse order. A step that fails part-way rolls back the steps
already done, so a failed register leaves Blender as it was.
"""
import bpy

from . import handlers, ops, props, ui

# Undo callables for the steps register() completed, in order.
_undo = []


def _register_classes(classes):
    for cls in classes:
        bpy.utils.register_class(cls)
        _undo.append(lambda cls=cls: bpy.utils.unregister_class(cls))


def register():
    if _undo:  # registered already (e.g. register called twice): start from scratch
        unregister()
    try:
        _register_classes(props.CLASSES)
        bpy.types.Scene.ols = bpy.props.PointerProperty(
            type=props.OLSSettings, name="Outdoor Light Scattering")
        _undo.append(_delete_scene_pointer)
        _register_classes(ops.CLASSES)
        handlers.register()
        _undo.append(handlers.unregister)
        _register_classes(ui.CLASSES)
    except Exception:
        unregister()
        raise


def _delete_scene_pointer():
    if hasattr(bpy.types.Scene, "ols"):
        del bpy.types.Scene.ols


def unregister():
    errors = []
    while _undo:
        step = _undo.pop()
        try:
            step()
        except Exception as exc:  # keep undoing the rest; report the first failure
            errors.append(exc)
    if errors:
        raise errors[0]
