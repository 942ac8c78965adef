"""Test configuration: make the repo root importable (``import lut_gen``).

Note: tests/ must stay a plain directory (no ``__init__.py``). The repo root is itself a
package (the extension's ``__init__.py``), so a ``tests/__init__.py`` would make pytest's
rootdir-walking import put the *parent* of the repo on sys.path.
"""
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import pytest  # noqa: E402


@pytest.fixture(scope="session")
def default_luts():
    """The default-resolution bake (the sample's 32 x 128 x 64 x 16 tables), once per session."""
    import lut_gen
    return lut_gen.bake(resolution="default")


@pytest.fixture(scope="session")
def draft_luts():
    import lut_gen
    return lut_gen.bake(resolution="draft")


# The extension's package name (blender_manifest.toml id). The repo root is imported under it so
# the extension's relative imports (``from ..lut_gen import ...``) resolve as in Blender, whatever
# the checkout directory is called.
EXTENSION_PACKAGE = "outdoor_light_scattering"


def import_extension(name=EXTENSION_PACKAGE):
    """Import the repo root as the package ``name`` (once per process) and return it."""
    import importlib.util

    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(
        name, ROOT / "__init__.py", submodule_search_locations=[str(ROOT)])
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[name]
        raise
    return module


@pytest.fixture
def addon_package():
    """The extension package, registered in Blender (bpy) for the test, unregistered after.

    Skips when bpy is not installed. Yields the package: ``pkg.addon.props``, ``pkg.lut_gen``
    (note: a different module object from the top-level ``lut_gen`` the numpy tests import, so
    compare its dataclasses with ``pkg.lut_gen.AtmosphereParams``).
    """
    pytest.importorskip("bpy")
    pkg = import_extension()
    pkg.register()
    try:
        yield pkg
    finally:
        pkg.unregister()
