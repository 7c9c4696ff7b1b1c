#!/usr/bin/env bash
# Runs the main demo: executes notebooks/00_tour.ipynb headless, writes it as HTML
# (3D views you can rotate in any browser, offline) together with the pictures it
# renders into out/, and says how to open the notebooks. The page is whole offline (csgnb.offline_html: MathJax
# inlined, no CDN script; it refuses to write a page that would fetch anything).
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
mkdir -p out
export CSGNB_OUT_DIR="$ROOT/out"
warm_numba_cache
# html: self-contained vtk.js views in the exported page (csgnb.display); static gives plain pictures.
export PYVISTA_JUPYTER_BACKEND="${CSGNB_DEMO_BACKEND:-html}"
echo "csgnb demo: executing notebooks/00_tour.ipynb ..."
python -m csgnb.offline_html notebooks/00_tour.ipynb --execute --output-dir out --timeout 900
echo
echo "Wrote:"
ls -1 out | sed 's/^/  out\//'
echo
echo "Open the tour:     out/00_tour.html (any browser; drag a 3D view to rotate it)"
echo "Explore the notebooks interactively:  bash scripts/lab.sh  (opens a working copy in lab/)"
