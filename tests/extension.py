"""What the tests share for reaching the code: the extension package imported under its
Blender id, its modules by dotted name, and the sample scene's builder script.

The repository root is itself a package (the extension's ``__init__.py``); it is imported under
the manifest's id so that the add-on's relative imports (``from ..lut_gen import ...``) resolve
as they do in Blender, whatever the checkout directory is called. ``lut_gen`` is also importable
on its own (the repository root is on sys.path): the numpy tests use that, and its dataclasses
are then other classes than ``extension_module("lut_gen").AtmosphereParams``.
"""
import importlib
import importlib.util
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SAMPLE_SCRIPT = ROOT / "sample_blend" / "build_sample.py"
EXTENSION_PACKAGE = "outdoor_light_scattering"     # blender_manifest.toml: id


def import_extension(name=EXTENSION_PACKAGE):
    """Import the repo root as the package ``name`` (once per process) and return it."""
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, ROOT / "__init__.py", submodule_search_locations=[str(ROOT)])
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[name]
        raise
    return module


def extension_module(dotted: str):
    """A module of the extension package by its dotted path from the root, e.g.
    ``extension_module("addon.scene.setup.wiring")`` or ``extension_module("lut_gen")``."""
    return importlib.import_module(f"{import_extension().__name__}.{dotted}")


class LazyModule:
    """A module imported on first attribute access: add-on modules import bpy, so a test file
    that names them at its top still collects where bpy is missing (its tests then skip)."""

    def __init__(self, dotted: str):
        self._dotted = dotted

    def __getattr__(self, attribute):
        return getattr(extension_module(self._dotted), attribute)


names = LazyModule("addon.scene.names")

_sample = {}


def sample_builder():
    """sample_blend/build_sample.py as a module (loaded once per process)."""
    if "module" not in _sample:
        spec = importlib.util.spec_from_file_location("ols_build_sample", SAMPLE_SCRIPT)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        _sample["module"] = module
    return _sample["module"]
