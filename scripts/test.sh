#!/usr/bin/env bash
# Runs every check (each step prints its time; the exit status is non-zero if any failed):
#   1. lint: `ruff check` on the package, tests and benchmarks; `nbqa ruff` on the notebooks;
#   2. kernels: `python -m csgnb.warmup --variants` compiles every numba kernel once, its parts in parallel processes
#      (minutes on a cold cache, seconds from the cache), so the workers below do not compile the same
#      kernels twice at once;
#   3. doctests: `pytest --doctest-modules csgnb`;
#   4. no-jit: a fast subset of the tests with NUMBA_DISABLE_JIT=1, so kernels stay valid Python
#      (the wide-integer kernels are LLVM intrinsics and exist only compiled: see NOJIT_TESTS below);
#      it runs in the background beside step 5 and its output is printed after it;
#   5. pytest on tests/ (hypothesis properties, exactness against Python ints and Fractions, the
#      browser test: every notebook in JupyterLab + headless Chromium) and every notebook executed
#      under nbval, on two pytest-xdist workers (`--dist loadscope`: a module's tests, a notebook's
#      cells, stay together and in order on one worker); the 20 slowest tests are listed at the end.
# Extra arguments go to the last pytest run: `bash scripts/test.sh -m slow` runs the long cases (fuzz runs, the
# browser test of the longer chapters), `-m "slow or not slow"` everything.
# CSGNB_TEST_WORKERS sets the number of workers (default 2; 0 runs step 5 in one process).
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
step "kernels (python -m csgnb.warmup --variants)" python -m csgnb.warmup --variants
step "doctests" python -m pytest --doctest-modules csgnb -q -p no:cacheprovider

workers="${CSGNB_TEST_WORKERS:-2}"
nojit_log="$(mktemp)"
nojit_t0=$SECONDS
env NUMBA_DISABLE_JIT=1 python -m pytest "${NOJIT_TESTS[@]}" -q -p no:cacheprovider > "$nojit_log" 2>&1 &
nojit_pid=$!
parallel=()
[ "$workers" -gt 0 ] && parallel=(-n "$workers" --dist loadscope)
step "pytest + nbval + browser (${workers} workers)" python -m pytest tests notebooks "${parallel[@]}" \
    --nbval-lax --nbval-current-env --nbval-sanitize-with notebooks/nbval_sanitize.cfg \
    --durations=20 -p no:cacheprovider "$@"
echo "=== csgnb test: no-jit subset (NUMBA_DISABLE_JIT=1), run beside the step above"
wait "$nojit_pid"
nojit_rc=$?
cat "$nojit_log"
rm -f "$nojit_log"
echo "=== csgnb test: no-jit subset: $([ $nojit_rc = 0 ] && echo ok || echo "FAILED (exit $nojit_rc)") in" \
     "$((SECONDS - nojit_t0)) s (wall, beside the step above)"
[ $nojit_rc = 0 ] || failed+=("no-jit subset")

if [ "${#failed[@]}" -gt 0 ]; then
    echo "csgnb test: FAILED: ${failed[*]}"
    exit 1
fi
# pytest's 5 ("no tests collected") is a failure above, never a success.
echo "csgnb test: all steps passed"
