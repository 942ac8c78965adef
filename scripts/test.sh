#!/usr/bin/env bash
# Run the test suite in .venv (created/updated by bootstrap.sh). Extra args go to pytest.
#   scripts/test.sh                       # whole suite (testpaths = ["tests"] in pyproject.toml)
#   scripts/test.sh tests/system/test_manifest.py -k build
#   scripts/test.sh tests/numpy_only            # one layer
#   scripts/test.sh -m "not slow"
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
bash scripts/bootstrap.sh
# No explicit "tests" argument: pyproject's testpaths supplies it when no paths are given,
# and passing it unconditionally would make `test.sh tests/numpy_only/test_x.py` run the whole suite.
exec .venv/bin/python -m pytest -q "$@"
