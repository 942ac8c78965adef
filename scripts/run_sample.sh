#!/usr/bin/env bash
# Bake the default tables and write a preview to build/sample.png. Extra args go to `lut_gen sample`.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
bash scripts/bootstrap.sh
mkdir -p build
exec .venv/bin/python -m lut_gen sample --out build/sample.png "$@"
