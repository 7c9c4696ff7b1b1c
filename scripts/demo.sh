#!/usr/bin/env bash
# Runs the main demo: executes notebooks/00_tour.ipynb headless, writes it as HTML
# together with the pictures it renders into out/, and says how to open the notebooks.
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
mkdir -p out
export CSGNB_OUT_DIR="$ROOT/out"
echo "csgnb demo: executing notebooks/00_tour.ipynb ..."
jupyter nbconvert --to html --execute notebooks/00_tour.ipynb --output-dir out \
    --ExecutePreprocessor.timeout=900 --log-level=WARN
echo
echo "Wrote:"
ls -1 out | sed 's/^/  out\//'
echo
echo "Open the tour:     out/00_tour.html (any browser)"
echo "Explore the notebooks interactively:  bash scripts/lab.sh"
