"""The layering rules that keep lut_gen usable outside Blender: ``import lut_gen`` loads neither
bpy nor mathutils nor the verification references, and no lut_gen module imports the add-on."""
import ast
import subprocess
import sys

from extension import ROOT


def test_import_lut_gen_loads_no_blender_and_no_references():
    code = ("import sys; sys.path.insert(0, sys.argv[1]); import lut_gen; "
            "print(sorted(m for m in sys.modules if m.split('.')[0] in {'bpy', 'mathutils'} "
            "or m.startswith('lut_gen.verify.')))")
    out = subprocess.run([sys.executable, "-c", code, str(ROOT)], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout


def test_lut_gen_imports_nothing_of_the_addon_or_blender():
    for path in (ROOT / "lut_gen").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                modules = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                modules = [("." * node.level) + (node.module or "")]
            else:
                continue
            for module in modules:
                top = module.split(".")[0]
                assert top not in {"bpy", "mathutils", "bpy_extras", "addon"}, (path, module)
                assert "addon" not in module.split("."), (path, module)


def test_model_and_tables_import_nothing_above_them():
    """model/ imports no other lut_gen folder; tables/ only model/ (docs/design.md: layers)."""
    allowed = {"model": {"model"}, "tables": {"model", "tables"}}
    for folder, may in allowed.items():
        for path in (ROOT / "lut_gen" / folder).glob("*.py"):
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, ast.ImportFrom) and node.level == 2 and node.module:
                    assert node.module.split(".")[0] in may, (path, node.module)
