"""Blender-side add-on code (operators, properties, UI) for Outdoor Light Scattering.

``register()`` registers, in order: the settings PropertyGroup and ``Scene.ols`` (props), the
operators (``ops.CLASSES``, when ``addon/ops.py`` exists) and their app handlers
(``ops.register_handlers()``, when defined), then the sidebar panel (ui). ``unregister()``
undoes the same steps in reverse order. A step that fails part-way rolls back the steps
already done, so a failed register leaves Blender as it was.
"""
import importlib
import importlib.util

import bpy

from . import props, ui

# Undo callables for the steps register() completed, in order.
_undo = []


def _ops_module():
    """``addon.ops`` if that module exists, else None (the operators land separately)."""
    name = f"{__package__}.ops"
    if importlib.util.find_spec(name) is None:
        return None
    return importlib.import_module(name)


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

        ops = _ops_module()
        if ops is not None:
            _register_classes(getattr(ops, "CLASSES", ()))
            if callable(getattr(ops, "register_handlers", None)):
                ops.register_handlers()
                if callable(getattr(ops, "unregister_handlers", None)):
                    _undo.append(ops.unregister_handlers)

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
