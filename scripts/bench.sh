#!/usr/bin/env bash
# Runs the benchmarks (each prints its table and writes out/bench/NAME.json), the peers (manifold3d, trimesh) in the
# same process. `bash scripts/bench.sh` runs all of them (tens of minutes); `bash scripts/bench.sh iterated milling`
# runs bench_iterated.py and bench_milling.py only. Take figures with nothing else running on the machine.
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
# The baselines (manifold3d, trimesh) at the versions of requirements-bench.lock (hash-checked; the other packages
# there are requirements.lock's own), unless CSGNB_DEPS=latest asked for the newest releases.
bench_stamp=.venv/.csgnb-bench-installed
bench_wanted="${CSGNB_DEPS:-lock} $(sha256sum requirements-bench.lock | cut -c1-16)"
if [ ! -f "$bench_stamp" ] || [ "$(cat "$bench_stamp")" != "$bench_wanted" ]; then
    if [ "${CSGNB_DEPS:-lock}" = latest ]; then
        echo "csgnb bench: pip install --upgrade -e .[bench] (the newest manifold3d, trimesh)"
        python -m pip install -q --upgrade -e ".[bench]"
    else
        echo "csgnb bench: pip install -r requirements-bench.lock (manifold3d, trimesh: the baselines, pinned)"
        python -m pip install -q --require-hashes -r requirements-bench.lock
        python -m pip install -q --no-deps -e .
    fi
    echo "$bench_wanted" > "$bench_stamp"
fi
mkdir -p out/bench
names=("$@")
if [ "${#names[@]}" -eq 0 ]; then
    for f in benchmarks/bench_*.py; do n=$(basename "$f" .py); names+=("${n#bench_}"); done
fi
failed=()
for n in "${names[@]}"; do
    f="benchmarks/bench_${n}.py"
    [ -f "$f" ] || { echo "csgnb bench: no $f" >&2; exit 2; }
    echo "=== csgnb bench: $n"
    python "$f" --json "out/bench/${n}.json" || failed+=("$n")
done
if [ "${#failed[@]}" -gt 0 ]; then echo "csgnb bench: FAILED: ${failed[*]}"; exit 1; fi
echo "csgnb bench: figures in out/bench/*.json"
