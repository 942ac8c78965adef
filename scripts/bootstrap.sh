#!/usr/bin/env bash
# Create/refresh the development virtualenv (.venv in the repo root) from requirements.txt.
#
# Idempotent: the sha256 of requirements.txt is stored in .venv/.requirements.sha256
# after a successful install; when it matches, nothing is done.
# Interpreter: $PYTHON if set, else `python3.11`, else `python3` if it is 3.11.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="$ROOT/.venv"
REQS="$ROOT/requirements.txt"
STAMP="$VENV/.requirements.sha256"
LOG="$VENV/bootstrap.log"

die() {
    echo "bootstrap: error: $*" >&2
    exit 1
}

is_py311() {
    "$1" -c 'import sys; sys.exit(0 if sys.version_info[:2] == (3, 11) else 1)' >/dev/null 2>&1
}

[[ -f "$REQS" ]] || die "missing $REQS"

# Serialise concurrent bootstraps (e.g. test.sh and run_sample.sh started together).
if command -v flock >/dev/null 2>&1; then
    exec 9<"${BASH_SOURCE[0]}"
    flock 9
fi

# Fast path: venv present, working, Python 3.11 and installed from this exact requirements.txt.
if [[ -x "$VENV/bin/python" && -f "$STAMP" ]] && is_py311 "$VENV/bin/python"; then
    want="$("$VENV/bin/python" -c 'import hashlib,sys; print(hashlib.sha256(open(sys.argv[1],"rb").read()).hexdigest())' "$REQS")"
    if [[ "$(cat "$STAMP")" == "$want" ]]; then
        echo "bootstrap: .venv is up to date" >&2
        exit 0
    fi
fi

# Find the interpreter.
PY=""
for cand in ${PYTHON:+"$PYTHON"} python3.11 python3; do
    if command -v "$cand" >/dev/null 2>&1 && is_py311 "$cand"; then
        PY="$(command -v "$cand")"
        break
    fi
done
[[ -n "$PY" ]] || die "Python 3.11 not found (tried \$PYTHON, python3.11, python3); install Python 3.11 or set PYTHON=/path/to/python3.11"

if [[ -x "$VENV/bin/python" ]] && is_py311 "$VENV/bin/python"; then
    echo "bootstrap: .venv is out of date with requirements.txt, installing" >&2
else
    echo "bootstrap: creating .venv with $PY and installing requirements.txt (first run takes a few minutes)" >&2
    rm -f "$STAMP"
    # --clear: recreate a broken/foreign venv from scratch.
    "$PY" -m venv --clear "$VENV" || die "could not create $VENV with $PY"
fi

rm -f "$STAMP"
if ! PIP_DISABLE_PIP_VERSION_CHECK=1 "$VENV/bin/python" -m pip install -q -r "$REQS" >"$LOG" 2>&1; then
    tail -n 40 "$LOG" >&2 || true
    die "pip install -r requirements.txt failed (full log: $LOG)"
fi

"$VENV/bin/python" -c 'import hashlib,sys; print(hashlib.sha256(open(sys.argv[1],"rb").read()).hexdigest())' "$REQS" >"$STAMP"
