#!/usr/bin/env bash
# Runs the benchmarks (each prints its table and writes out/bench/NAME.json), the peers (manifold3d, trimesh) in the
# same process. `bash scripts/bench.sh` runs all of them (tens of minutes); `bash scripts/bench.sh iterated milling`
# runs bench_iterated.py and bench_milling.py only. Take figures with nothing else running on the machine.
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
if ! python -c "import manifold3d, trimesh" 2>/dev/null; then
    echo "csgnb bench: pip install -e .[bench] (manifold3d, trimesh: the baselines)"
    python -m pip install -q -e ".[bench]"
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
