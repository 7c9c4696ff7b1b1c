#!/usr/bin/env bash
# Runs every test: pytest on tests/ (hypothesis properties, exactness against Python
# ints and Fractions) and every notebook executed under nbval. Extra arguments go to
# pytest, e.g. `bash scripts/test.sh -m slow` for the long fuzz runs.
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
set +e
python -m pytest tests notebooks \
    --nbval-lax --nbval-current-env --nbval-sanitize-with notebooks/nbval_sanitize.cfg \
    --durations=20 -p no:cacheprovider "$@"
status=$?
set -e
# pytest's 5 means "no tests collected": treat it as a failure, never as success.
exit $status
