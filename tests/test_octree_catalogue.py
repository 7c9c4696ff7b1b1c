"""The octree workpiece's public API called with the bad-argument table of ``test_input_catalogue``.

Every call must succeed or raise a csgnb error / ``TypeError`` with a message that names the problem -- never a
raw numpy / numba / Python error. Methods are found by walking the instance, so new public methods are covered.
Calls run in a temporary folder (a string may be taken as a path to write).
"""

from __future__ import annotations

import inspect

import pytest

from csgnb import octree
from csgnb.octree import Tool, Workpiece
from tests.test_input_catalogue import _raw_errors


def _callables():
    w = Workpiece.box([0, 0, 0], [8, 8, 8], threshold=16)
    for name, member in inspect.getmembers(w, callable):
        if not name.startswith("_") and not isinstance(member, type):
            yield f"Workpiece().{name}", member
    for name in ("box", "empty", "from_mesh", "load"):
        yield f"Workpiece.{name}", getattr(Workpiece, name)
    yield "Workpiece", Workpiece
    for name in ("from_hull", "from_mesh", "from_bsp"):
        yield f"Tool.{name}", getattr(Tool, name)
    for name in octree.__all__:
        obj = getattr(octree, name)
        if callable(obj) and not isinstance(obj, type):
            yield f"csgnb.octree.{name}", obj


CALLABLES = dict(_callables())


@pytest.mark.parametrize("name", sorted(CALLABLES))
def test_bad_arguments_get_clear_errors(name, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    problems = _raw_errors(CALLABLES[name])
    assert not problems, f"{name}:\n" + "\n".join(problems)


def test_the_catalogue_covers_the_workpiece_api():
    for expected in ("Workpiece().difference", "Workpiece().classify", "Workpiece().cell_volume",
                     "Workpiece().cells_meeting", "Workpiece().save", "Workpiece.box", "Workpiece.load"):
        assert expected in CALLABLES
