"""The milling applications' public API (G-code, tool tables, milling, export, the CLI) with bad inputs.

Every call must succeed or raise a csgnb error / ``TypeError`` / ``FileNotFoundError`` with a message -- never a
raw numpy or Python error. The keyword options of :func:`csgnb.apps.gcode.parse` are tried one at a time, and the
command line with bad option values: a bad value exits 2 with a one-line ``error:``, never a traceback.
"""

from __future__ import annotations

import pytest

from csgnb import mill
from csgnb.apps import export, gcode, milling, tooltable
from tests.test_input_catalogue import _bad_values, _raw_errors

CALLABLES = {f"{m.__name__}.{n}": getattr(m, n) for m in (gcode, tooltable, milling, export) for n in m.__all__
             if callable(getattr(m, n)) and not isinstance(getattr(m, n), type)}


@pytest.mark.parametrize("name", sorted(CALLABLES))
def test_bad_arguments_get_clear_errors(name, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    problems = _raw_errors(CALLABLES[name])
    assert not problems, f"{name}:\n" + "\n".join(problems)


@pytest.mark.parametrize("option", ["start", "on_unsupported", "dialect", "tool_lengths", "home", "block_delete",
                                    "max_loop_passes"])
def test_bad_parse_options_get_clear_errors(option):
    problems = _raw_errors(lambda value: gcode.parse("G0 X1\nG1 X2 F100\n", **{option: value}))
    assert not problems, f"parse({option}=...):\n" + "\n".join(problems)


@pytest.mark.parametrize("argv", [
    ["--stock", "10", "10", "nan"], ["--stock", "10", "10", "-1"], ["--rapid-rate", "0"],
    ["--chord-tolerance", "1e-12"], ["--checkpoint-every", "-3"], ["--segments", "2"], ["--resolution", "0"],
    ["--tool", "nonsense:3"], ["--tool", "flat:-6"], ["--tool", "2=flat:6", "--tool", "2=flat:3"],
    ["--tool-table", "missing.tbl"], ["--start", "inf", "0", "0"],
])
def test_bad_command_lines_exit_2_with_one_error_line(argv, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "p.nc").write_text("G0 X1 Y1 Z5\nG1 Z-1 F100\nG1 X5\n")
    base = ["p.nc", "--stock", "10", "10", "3", "--no-progress"]
    assert mill.main(base + argv) == 2
    err = capsys.readouterr().err
    assert "error:" in err and "Traceback" not in err


def test_the_catalogue_sees_the_values():
    assert len(_bad_values()) > 10 and "csgnb.apps.gcode.parse" in CALLABLES
