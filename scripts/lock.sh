#!/usr/bin/env bash
# Refreshes requirements.lock: resolves pyproject.toml's dependencies with the dev extra to the newest versions
# on PyPI for Python 3.11 on x86-64 Linux, with every file's hash. The set-up (scripts/setup.sh) installs exactly
# this lock, so a fresh machine gets what CI tested. After refreshing, run `CSGNB_DEPS=lock bash scripts/test.sh`
# and commit the lock only if it passes; `CSGNB_DEPS=latest bash scripts/test.sh` tries the newest versions
# without touching the lock.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
TOOLS="$ROOT/.venv-lock"
if [ ! -x "$TOOLS/bin/uv" ]; then
    python3 -m pip install -q --target "$TOOLS" uv
fi
PYTHONPATH="$TOOLS" "$TOOLS/bin/uv" pip compile pyproject.toml --extra dev --generate-hashes \
    --python-version 3.11.7 --python-platform x86_64-manylinux_2_28 --upgrade \
    --custom-compile-command "bash scripts/lock.sh" -o requirements.lock "$@"
echo "requirements.lock refreshed: $(grep -c '==' requirements.lock) pinned packages"
