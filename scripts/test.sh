#!/usr/bin/env bash
# Runs every check, in order (each step prints its time; the exit status is non-zero if any failed):
#   1. lint: `ruff check` on the package, tests and benchmarks; `nbqa ruff` on the notebooks;
#   2. doctests: `pytest --doctest-modules csgnb`;
#   3. no-jit: a fast subset of the tests with NUMBA_DISABLE_JIT=1, so kernels stay valid Python
#      (the wide-integer kernels are LLVM intrinsics and exist only compiled: see NOJIT_TESTS below);
#   4. pytest on tests/ (hypothesis properties, exactness against Python ints and Fractions, the
#      browser test: every notebook in JupyterLab + headless Chromium) and every notebook executed
#      under nbval.
# Extra arguments go to the last pytest run, e.g. `bash scripts/test.sh -m slow` for the long fuzz runs.
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
set +e

# Tests whose kernels run as plain Python under NUMBA_DISABLE_JIT=1: the quadric, CSG and sampling kernels are
# ordinary numba code. Everything that reaches a wide-integer predicate (csgnb.exact.intrinsics: exact, mesh, bsp)
# cannot: an intrinsic has no Python implementation. test_quadric_heightfield.py and test_sampling_geometry.py
# are left out: two quadric kernels rely on numba's IEEE math.sqrt (NaN) where Python raises (docs/ARCHITECTURE.md).
NOJIT_TESTS=(
    tests/test_quadric_basics.py
    tests/test_quadric_evaluate.py
    tests/test_quadric_distance.py
    tests/test_quadric_regions.py
    tests/test_csg_graph.py
    tests/test_csg_normal_form.py
    tests/test_csg_bounds.py
    tests/test_csg_distance.py
    tests/test_csg_raycast.py
    tests/test_sampling_errors.py
    tests/test_sampling_guarantee.py
)

failed=()
step() {  # step NAME COMMAND...: run it, time it, remember a failure
    local name=$1 t0=$SECONDS rc
    shift
    echo "=== csgnb test: $name"
    "$@"
    rc=$?
    echo "=== csgnb test: $name: $([ $rc = 0 ] && echo ok || echo "FAILED (exit $rc)") in $((SECONDS - t0)) s"
    [ $rc = 0 ] || failed+=("$name")
}

step "ruff (package, tests, benchmarks)" ruff check csgnb tests benchmarks
step "nbqa ruff (notebooks)" nbqa ruff notebooks
step "doctests" python -m pytest --doctest-modules csgnb -q -p no:cacheprovider
step "no-jit subset (NUMBA_DISABLE_JIT=1)" env NUMBA_DISABLE_JIT=1 python -m pytest "${NOJIT_TESTS[@]}" -q \
    -p no:cacheprovider
step "pytest + nbval + browser" python -m pytest tests notebooks \
    --nbval-lax --nbval-current-env --nbval-sanitize-with notebooks/nbval_sanitize.cfg \
    --durations=20 -p no:cacheprovider "$@"

if [ "${#failed[@]}" -gt 0 ]; then
    echo "csgnb test: FAILED: ${failed[*]}"
    exit 1
fi
# pytest's 5 ("no tests collected") is a failure above, never a success.
echo "csgnb test: all steps passed"
