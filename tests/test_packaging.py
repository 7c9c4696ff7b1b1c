"""The project's set-up files agree with each other."""

import pathlib
import re
import tomllib

ROOT = pathlib.Path(__file__).resolve().parents[1]


def _name(requirement: str) -> str:
    return re.split(r"[<>=!~\[ ;]", requirement.strip(), maxsplit=1)[0].lower().replace("_", "-")


def test_environment_yml_lists_the_same_packages_as_pyproject():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    pip_names = {_name(r) for r in project["dependencies"] + project["optional-dependencies"]["dev"]}
    conda_names = set()
    in_deps = False
    for line in (ROOT / "environment.yml").read_text().splitlines():
        if line.startswith("dependencies:"):
            in_deps = True
            continue
        # conda packages ("  - name"), and pip-only ones under "  - pip:" ("      - name"; not "-e .")
        m = re.match(r"^(?:  |      )- ([A-Za-z0-9_.\-]+)", line)
        if in_deps and m and m.group(1) not in {"python", "pip", "-e"}:
            conda_names.add(_name(m.group(1)))
    assert pip_names == conda_names


def test_ci_runs_the_readme_test_command_and_nothing_else():
    ci = (ROOT / ".ci" / "run").read_text()
    commands = [line for line in ci.splitlines() if line.strip() and not line.startswith("#")]
    assert commands[-1].strip() == "exec bash ./scripts/test.sh"
    assert "bash scripts/test.sh" in (ROOT / "README.md").read_text()


def test_every_notebook_chapter_present_is_numbered():
    names = sorted(p.stem for p in (ROOT / "notebooks").glob("*.ipynb"))
    assert "00_tour" in names
    assert all(re.match(r"^\d\d_[a-z0-9_]+$", n) for n in names)


def _locked(name: str = "requirements.lock") -> dict[str, str]:
    text = (ROOT / name).read_text()
    return {m.group(1).lower().replace("_", "-"): m.group(2)
            for m in re.finditer(r"^([A-Za-z0-9_.\-]+)==(\S+)", text, re.MULTILINE)}


def test_the_lock_pins_every_dependency_with_hashes_and_the_setup_installs_it():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    locked = _locked()
    wanted = {_name(r) for r in project["dependencies"] + project["optional-dependencies"]["dev"]}
    assert wanted <= set(locked), f"not in requirements.lock (run bash scripts/lock.sh): {wanted - set(locked)}"
    text = (ROOT / "requirements.lock").read_text()
    blocks = re.split(r"\n(?=[A-Za-z0-9_.\-]+==)", text.split("\n", 2)[2])
    assert all("--hash=sha256:" in b for b in blocks if "==" in b)
    setup = (ROOT / "scripts" / "setup.sh").read_text()
    assert "--require-hashes -r requirements.lock" in setup and 'CSGNB_DEPS:-lock' in setup


def test_the_bench_lock_is_the_lock_plus_the_baselines_and_bench_sh_installs_it():
    """The benchmarks' baselines are pinned too (requirements-bench.lock, hashes included), at versions that agree
    with requirements.lock for every package both pin: a benchmark runs on the tested packages and a known
    manifold3d, whose figures the documents quote."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    main, bench = _locked(), _locked("requirements-bench.lock")
    baselines = {_name(r) for r in project["optional-dependencies"]["bench"]}
    missing = baselines - set(bench)
    assert not missing, f"not in requirements-bench.lock (run bash scripts/lock.sh): {missing}"
    differ = {k: (v, bench[k]) for k, v in main.items() if k in bench and bench[k] != v}
    assert not differ, f"requirements-bench.lock disagrees with requirements.lock (run bash scripts/lock.sh): {differ}"
    assert set(main) <= set(bench), f"requirements-bench.lock lacks {set(main) - set(bench)}"
    text = (ROOT / "requirements-bench.lock").read_text()
    blocks = re.split(r"\n(?=[A-Za-z0-9_.\-]+==)", text.split("\n", 2)[2])
    assert all("--hash=sha256:" in b for b in blocks if "==" in b)
    assert "--require-hashes -r requirements-bench.lock" in (ROOT / "scripts" / "bench.sh").read_text()


def test_the_installed_versions_are_the_locked_ones():
    """What the tests run on is what the lock says (unless CSGNB_DEPS=latest asked for the newest releases)."""
    import os
    from importlib.metadata import PackageNotFoundError, version

    if os.environ.get("CSGNB_DEPS", "lock") == "latest":
        return
    wrong = {}
    for name, pinned in _locked().items():
        try:
            got = version(name)
        except PackageNotFoundError:
            got = None
        if got != pinned:
            wrong[name] = (pinned, got)
    assert not wrong, f"installed versions differ from requirements.lock (re-run scripts/setup.sh): {wrong}"


def test_every_chapter_checks_the_legibility_of_what_it_shows():
    """Each chapter applies csgnb's style and ends with a checked legibility report (csgnb.plotting), so a figure
    whose text shrinks under 11 px on screen, or whose labels collide, fails its notebook under nbval."""
    import json

    for path in sorted((ROOT / "notebooks").glob("*.ipynb")):
        cells = [c for c in json.loads(path.read_text())["cells"] if c["cell_type"] == "code"]
        sources = ["".join(c["source"]) for c in cells]
        assert any("use_style()" in s for s in sources[:3]), f"{path.name}: no use_style() among its first cells"
        last = sources[-1]
        assert "# NBVAL_CHECK_OUTPUT" in last and "legibility_report()" in last, f"{path.name}: no report at the end"
        shown = "".join("".join(o.get("text", "")) for o in cells[-1].get("outputs", []))
        assert "every text at least 11 px on screen" in shown and "no texts overlap" in shown, (path.name, shown)
