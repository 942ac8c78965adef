"""Write the table of every control into docs/controls.md, made from the controls registry
(addon/controls.py). Run it after adding or changing a control; a test fails while the two differ.

    .venv/bin/python scripts/controls_table.py           # rewrite the table in place
    .venv/bin/python scripts/controls_table.py --check   # exit 1 when the docs are out of date
"""
import importlib
import importlib.util
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = "outdoor_light_scattering"
DOCS = ROOT / "docs" / "controls.md"


def controls_module():
    """addon.controls without registering the add-on (it needs nothing of Blender's state)."""
    if PACKAGE not in sys.modules:
        spec = importlib.util.spec_from_file_location(PACKAGE, ROOT / "__init__.py",
                                                      submodule_search_locations=[str(ROOT)])
        module = importlib.util.module_from_spec(spec)
        sys.modules[PACKAGE] = module
        spec.loader.exec_module(module)
    return importlib.import_module(PACKAGE + ".addon.controls")


def main(argv):
    controls = controls_module()
    text = DOCS.read_text()
    try:
        made = controls.replace_docs_table(text)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    if "--check" in argv:
        if made != text:
            print("docs/controls.md's table is out of date: run .venv/bin/python scripts/controls_table.py",
                  file=sys.stderr)
            return 1
        return 0
    if made != text:
        tmp = DOCS.with_suffix(".md.tmp")
        tmp.write_text(made)
        tmp.replace(DOCS)           # atomic: a reader never sees half a file
        print(f"wrote {DOCS.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
