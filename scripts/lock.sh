#!/usr/bin/env bash
# Writes requirements.lock: resolves pyproject.toml's dependencies with the dev extra for Python 3.11 on x86-64
# Linux, with every file's hash, keeping the versions already pinned (a new dependency gets its newest version);
# then requirements-bench.lock: the same plus the bench extra (manifold3d, trimesh: the benchmarks' baselines),
# constrained to requirements.lock's versions, so the benchmarks run on exactly the tested packages and a known
# manifold3d (scripts/bench.sh installs it);
# `bash scripts/lock.sh --upgrade` moves every package to its newest version. The set-up (scripts/setup.sh) installs exactly
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
    --python-version 3.11.7 --python-platform x86_64-manylinux_2_28 \
    --custom-compile-command "bash scripts/lock.sh" -o requirements.lock "$@"
echo "requirements.lock written: $(grep -c '==' requirements.lock) pinned packages"
pins=".venv-lock/pins-of-requirements.lock.txt"  # a fixed name: the lock names it in its comments
grep -E '^[A-Za-z0-9_.-]+==' requirements.lock | sed 's/ \\$//' > "$pins"
PYTHONPATH="$TOOLS" "$TOOLS/bin/uv" pip compile pyproject.toml --extra dev --extra bench --generate-hashes \
    --python-version 3.11.7 --python-platform x86_64-manylinux_2_28 -c "$pins" \
    --custom-compile-command "bash scripts/lock.sh" -o requirements-bench.lock
rm -f "$pins"
echo "requirements-bench.lock written: $(grep -c '==' requirements-bench.lock) pinned packages"
