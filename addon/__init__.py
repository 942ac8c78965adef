"""Blender-side add-on code (operators, properties, UI) for Outdoor Light Scattering."""


def register():
    pass


def unregister():
    pass
