"""Test configuration for every layer (tests/numpy_only, addon, twins, system).

The repo root goes on sys.path (``import lut_gen``) and so does tests/ (the shared helpers:
extension.py, render_util.py, rays.py). tests/ and its layer folders stay plain directories (no
``__init__.py``): the repo root is itself a package (the extension's ``__init__.py``), and a
``tests/__init__.py`` would make pytest's rootdir-walking import put the *parent* of the repo on
sys.path.
"""
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
for path in (ROOT, ROOT / "tests"):
    if str(path) not in sys.path:
        sys.path.insert(0, str(path))

import pytest  # noqa: E402

from extension import EXTENSION_PACKAGE, import_extension  # noqa: E402,F401 (benches import them from here)


@pytest.fixture(scope="session")
def default_luts():
    """The default-resolution bake (the sample's 32 x 128 x 64 x 16 tables), once per test run."""
    import lut_gen
    return lut_gen.bake(resolution="default")


@pytest.fixture(scope="session")
def draft_luts():
    import lut_gen
    return lut_gen.bake(resolution="draft")


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
