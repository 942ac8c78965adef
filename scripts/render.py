"""Headless render entry point (see addon/batch.py). Works with the bpy module and with
`blender --background [file.blend] --python scripts/render.py -- [options]`."""
import importlib
import importlib.util
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = "outdoor_light_scattering"


def import_extension():
    """The repo root as the extension package, registered in Blender."""
    if PACKAGE not in sys.modules:
        spec = importlib.util.spec_from_file_location(PACKAGE, ROOT / "__init__.py",
                                                      submodule_search_locations=[str(ROOT)])
        module = importlib.util.module_from_spec(spec)
        sys.modules[PACKAGE] = module
        spec.loader.exec_module(module)
    package = sys.modules[PACKAGE]
    package.register()
    return package


def script_args():
    return sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]


if __name__ == "__main__":
    import_extension()
    batch = importlib.import_module(PACKAGE + ".addon.batch")
    code = batch.main(script_args())
    sys.stdout.flush()
    sys.exit(code)
