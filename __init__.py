"""Outdoor Light Scattering: physically based sky and aerial perspective for Blender.

Extension entry point. Importing this package is deliberately cheap: the add-on
(``addon`` subpackage, which pulls in bpy and numpy) is imported only on register.
"""


def register():
    from . import addon

    addon.register()


def unregister():
    from . import addon

    addon.unregister()
