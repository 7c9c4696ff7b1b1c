"""The benchmarks run and report: a small run of each workload that needs nothing but the baselines' extra.

Their figures are not checked here (speed is measured by the benchmarks themselves, never asserted in a test); what
is checked is that a workload runs end to end, prints its report and writes its JSON. The benchmarks' baselines
(manifold3d) come with ``scripts/bench.sh``'s lock, not the test environment: without them these tests skip.
"""

import json
import subprocess
import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parent.parent / "benchmarks"


def test_bench_iterated_reports_the_dome_and_the_lattice(tmp_path):
    """A report line of one workload once read keys another workload's result has (the dome's report printed the
    mesh drill's tools line: KeyError 'fill' after its figures)."""
    pytest.importorskip("manifold3d")
    out = tmp_path / "iterated.json"
    run = subprocess.run([sys.executable, str(BENCHMARKS / "bench_iterated.py"), "--workloads", "dome", "lattice",
                          "--dome-steps", "20", "--lattice-ops", "20", "--json", str(out)],
                         capture_output=True, text=True, cwd=BENCHMARKS.parent, timeout=600)
    assert run.returncode == 0, run.stderr[-2000:]
    assert "dome carve, 20 capsules" in run.stdout and "cube lattice, 20 Booleans" in run.stdout
    result = json.loads(out.read_text())
    assert set(result["workloads"]) == {"dome", "lattice"}
    assert result["workloads"]["lattice"]["exact_volume_mismatches"] == 0
