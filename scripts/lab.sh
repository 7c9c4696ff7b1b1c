#!/usr/bin/env bash
# Opens the notebooks in JupyterLab, on a working copy: exploring (and JupyterLab's autosave)
# never rewrites the committed notebooks, whose outputs the tests compare against.
# The copy lives in lab/ (ignored by git); notebooks already there are kept, so your edits survive
# between sessions. `bash scripts/lab.sh --fresh` replaces them with the committed versions.
# Other arguments go to `jupyter lab`.
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
LAB_DIR="$ROOT/lab"
fresh=0
args=()
for a in "$@"; do
    if [ "$a" = "--fresh" ]; then fresh=1; else args+=("$a"); fi
done
mkdir -p "$LAB_DIR"
copied=()
for nb in notebooks/*.ipynb; do
    target="$LAB_DIR/$(basename "$nb")"
    if [ "$fresh" = 1 ] || [ ! -f "$target" ]; then
        cp "$nb" "$target"
        copied+=("$(basename "$nb")")
    fi
done
echo "csgnb lab: working copy of the notebooks in lab/ (git ignores it; notebooks/ is never modified)."
if [ "${#copied[@]}" -gt 0 ]; then
    echo "  copied from notebooks/: ${copied[*]}"
fi
echo "  notebooks already in lab/ were kept; start over with: bash scripts/lab.sh --fresh"
warm_numba_cache
# Interactive 3D views (csgnb.display: self-contained vtk.js, rotatable, also in HTML exports).
export PYVISTA_JUPYTER_BACKEND=html
export CSGNB_OUT_DIR="$LAB_DIR/out"
extra=()
[ "$(id -u)" = "0" ] && extra+=(--allow-root)
exec jupyter lab "$LAB_DIR" "${extra[@]}" "${args[@]}"
