#!/usr/bin/env bash
# The main job: bake the default tables (cached), build the sample terrain scene, wire it and
# render it headless with Cycles to build/sample.png. Extra args go to scripts/render.py
# (e.g. --engine EEVEE, --resolution 1280x720, --samples 64, --sun-elevation 10).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
bash scripts/bootstrap.sh
mkdir -p build
exec .venv/bin/python scripts/render.py --sample --resolution 960x540 --samples 32 \
    --sun-elevation 15 --sun-azimuth 35 --output build/sample.png "$@"
