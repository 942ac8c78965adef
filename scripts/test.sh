#!/usr/bin/env bash
# Run the test suite in .venv (created/updated by bootstrap.sh). Extra args go to pytest.
#   scripts/test.sh                       # whole suite (testpaths = ["tests"] in pyproject.toml)
#   scripts/test.sh tests/system/test_manifest.py -k build
#   scripts/test.sh tests/numpy_only            # one layer
#   scripts/test.sh -m "not slow"
#   OLS_TEST_WORKERS=0 scripts/test.sh tests/addon -x   # in one process (-x, pdb, -s output)
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
bash scripts/bootstrap.sh
# No explicit "tests" argument: pyproject's testpaths supplies it when no paths are given,
# and passing it unconditionally would make `test.sh tests/numpy_only/test_x.py` run the whole suite.
# Two workers (pytest-xdist), each test file on one of them (module fixtures are shared within a
# file): much of a test's time is single-threaded bpy work (building node groups, wiring scenes),
# so CI's two cores finish the suite sooner. OLS_TEST_WORKERS=0 runs it in this process.
exec .venv/bin/python -m pytest -q -n "${OLS_TEST_WORKERS:-2}" --dist loadfile "$@"
