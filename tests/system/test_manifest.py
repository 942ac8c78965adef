"""Validate blender_manifest.toml and the extension build.

The CLI checks use Blender's own extension tool (``blender_ext.py``) shipped inside the
bpy wheel, run with the plain Python interpreter (it does not import bpy). It is the same
code behind ``blender --command extension validate|build``.
"""
import importlib.util
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest
from extension import ROOT

MANIFEST = ROOT / "blender_manifest.toml"


def _bpy_dir():
    # find_spec locates the wheel without importing bpy (which would boot Blender).
    spec = importlib.util.find_spec("bpy")
    if spec is None or spec.origin is None:
        pytest.skip("bpy is not installed")
    return Path(spec.origin).parent


@pytest.fixture(scope="module")
def blender_ext():
    """Path to bl_pkg's CLI and to Blender's valid-tags list inside the bpy wheel."""
    bpy_dir = _bpy_dir()
    # bpy/<major.minor>/scripts/...; e.g. bpy/5.0/scripts/addons_core/bl_pkg/cli/blender_ext.py
    cli = sorted(bpy_dir.glob("*/scripts/addons_core/bl_pkg/cli/blender_ext.py"))
    tags = sorted(bpy_dir.glob("*/scripts/modules/_bpy_internal/extensions/tags.py"))
    assert cli, f"blender_ext.py not found under {bpy_dir}"
    assert tags, f"tags.py not found under {bpy_dir}"
    return cli[-1], tags[-1]


def _run(cmd):
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, (
        f"{' '.join(map(str, cmd))}\nexit {proc.returncode}\n"
        f"stdout:\n{proc.stdout}\nstderr:\n{proc.stderr}"
    )
    return proc


def test_manifest_fields():
    data = tomllib.loads(MANIFEST.read_text(encoding="utf-8"))
    assert data["schema_version"] == "1.0.0"
    assert data["id"] == "outdoor_light_scattering"
    assert data["type"] == "add-on"
    assert data["blender_version_min"] == "5.0.0"
    assert data["license"] == ["SPDX:GPL-3.0-or-later"]
    tagline = data["tagline"]
    assert 0 < len(tagline) <= 64
    assert tagline[-1].isalnum()
    # numpy is bundled with Blender; OpenEXR is not and must not be shipped as a wheel.
    assert "wheels" not in data


@pytest.mark.bpy
def test_manifest_validates(blender_ext):
    cli, tags = blender_ext
    # --valid-tags: the standalone CLI skips tag checks unless given Blender's tag list
    # (``blender --command extension validate`` passes the same file implicitly).
    _run([sys.executable, str(cli), "validate", "--valid-tags", str(tags), str(ROOT)])


@pytest.mark.bpy
def test_extension_builds(blender_ext, tmp_path):
    cli, tags = blender_ext
    _run([
        sys.executable, str(cli), "build",
        "--source-dir", str(ROOT),
        "--output-dir", str(tmp_path),
        "--valid-tags", str(tags),
    ])
    zips = list(tmp_path.glob("*.zip"))
    assert [z.name for z in zips] == ["outdoor_light_scattering-0.1.0.zip"]

    with zipfile.ZipFile(zips[0]) as zf:
        names = zf.namelist()
    assert "blender_manifest.toml" in names
    assert "__init__.py" in names
    assert "addon/__init__.py" in names

    excluded_top = ("tests/", ".venv/", ".git/", ".ci/", "scripts/", "build/", "cache/", "bench/", "dist/")
    offenders = [
        n for n in names
        if n.startswith(excluded_top)
        or "__pycache__/" in n
        or n.endswith(".pyc")
        or n in ("requirements.txt", "pyproject.toml", ".gitignore")
    ]
    assert not offenders, f"dev files leaked into the package: {offenders}"
