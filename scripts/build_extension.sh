#!/usr/bin/env bash
# Build the extension zip into dist/ with the extension CLI shipped in the bpy wheel (the same
# code as `blender --command extension build`), after validating the manifest.
#   scripts/build_extension.sh            # dist/outdoor_light_scattering-<version>.zip
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
bash scripts/bootstrap.sh
B=.venv/lib/python3.11/site-packages/bpy/5.0
CLI="$B/scripts/addons_core/bl_pkg/cli/blender_ext.py"
TAGS="$B/scripts/modules/_bpy_internal/extensions/tags.py"
[[ -f "$CLI" ]] || { echo "build_extension: error: $CLI not found (is bpy 5.0.1 installed in .venv?)" >&2; exit 1; }
mkdir -p dist
.venv/bin/python "$CLI" validate "$ROOT" --valid-tags "$TAGS"
.venv/bin/python "$CLI" build --source-dir . --output-dir dist --valid-tags "$TAGS"
