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
