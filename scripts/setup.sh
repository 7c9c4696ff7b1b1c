#!/usr/bin/env bash
# Shared set-up for demo.sh, test.sh and lab.sh: sourced, never run on its own.
# Creates .venv, installs csgnb with its dev extras, installs the system packages
# (EGL + Mesa's software driver for headless VTK; Debian's chromium for the
# browser test) and exports the environment that makes pyvista render off-screen
# and notebooks run reproducibly. `warm_numba_cache` (called by demo.sh and lab.sh)
# compiles the kernels up front, with a progress bar.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

PYTHON="${PYTHON:-python3}"
APT_PACKAGES=(libegl1 libgl1-mesa-dri chromium)

missing_apt=()
for pkg in "${APT_PACKAGES[@]}"; do
    dpkg -s "$pkg" >/dev/null 2>&1 || missing_apt+=("$pkg")
done
if [ "${#missing_apt[@]}" -gt 0 ]; then
    if [ "$(id -u)" = "0" ]; then
        echo "csgnb setup: installing ${missing_apt[*]} (headless rendering, browser test) with apt-get"
        export DEBIAN_FRONTEND=noninteractive
        apt-get update -qq
        apt-get install -y -qq --no-install-recommends "${missing_apt[@]}" >/dev/null
    else
        echo "csgnb setup: headless rendering and the browser test need the Debian packages: ${missing_apt[*]}" >&2
        echo "  run as root:  apt-get install -y --no-install-recommends ${missing_apt[*]}" >&2
        exit 1
    fi
fi

if [ ! -x .venv/bin/python ]; then
    echo "csgnb setup: creating .venv with $($PYTHON --version)"
    "$PYTHON" -m venv .venv
fi
# Dependencies: by default exactly requirements.lock (pinned versions and file hashes: a fresh machine gets what CI
# tested; scripts/lock.sh refreshes it). CSGNB_DEPS=latest installs the newest releases instead (to find breakage
# from new versions deliberately). Reinstall only when the lock, the package metadata or the mode changed.
deps_mode="${CSGNB_DEPS:-lock}"
case "$deps_mode" in
    lock|latest) ;;
    *) echo "csgnb setup: CSGNB_DEPS must be 'lock' (default) or 'latest', got '$deps_mode'" >&2; exit 2 ;;
esac
stamp=.venv/.csgnb-installed
wanted="$deps_mode $(cat pyproject.toml requirements.lock | sha256sum | cut -c1-16)"
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$wanted" ]; then
    .venv/bin/python -m pip install -q --upgrade pip
    if [ "$deps_mode" = lock ]; then
        echo "csgnb setup: pip install -r requirements.lock (pinned, hash-checked; first time: a few minutes)"
        .venv/bin/python -m pip install -q --require-hashes -r requirements.lock
        .venv/bin/python -m pip install -q --no-deps -e .
    else
        echo "csgnb setup: pip install --upgrade -e .[dev] (CSGNB_DEPS=latest: the newest releases, not the lock)"
        .venv/bin/python -m pip install -q --upgrade --upgrade-strategy eager -e ".[dev]"
    fi
    echo "$wanted" > "$stamp"
fi

export PATH="$ROOT/.venv/bin:$PATH"
# Headless VTK through EGL (software llvmpipe); the variable must always be set,
# otherwise VTK prints a timestamped X-server warning that breaks output checks.
export VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow
export PYVISTA_OFF_SCREEN=true
# static: deterministic PNGs for nbval and CI. lab.sh and demo.sh switch to html (csgnb.display).
export PYVISTA_JUPYTER_BACKEND=static
# trame-vtklocal (a dependency of pyvista's html backend) downloads a wasm bundle unless this names a folder.
export VTK_WASM_DIR_OVERRIDE="$ROOT/.venv/no-vtk-wasm"
mkdir -p "$VTK_WASM_DIR_OVERRIDE"
export PYTHONHASHSEED=0
export NUMBA_CACHE_DIR="$ROOT/.numba_cache"

# Compiles (or loads from .numba_cache) the kernels the notebooks use, with a progress bar.
warm_numba_cache() {
    python -m csgnb.warmup
}
