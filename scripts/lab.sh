#!/usr/bin/env bash
# Opens the notebooks in JupyterLab (the optional third command).
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
export PYVISTA_OFF_SCREEN=false
unset PYVISTA_JUPYTER_BACKEND
extra=()
[ "$(id -u)" = "0" ] && extra+=(--allow-root)
exec jupyter lab notebooks "${extra[@]}" "$@"
