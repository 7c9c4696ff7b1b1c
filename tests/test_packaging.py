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
        m = re.match(r"^  - ([A-Za-z0-9_.\-]+)", line)
        if in_deps and m and m.group(1) not in {"python", "pip"}:
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
