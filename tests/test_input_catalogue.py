"""Every public function of csgnb.exact and csgnb.bsp, called with a table of bad arguments.

Each call must either succeed (the value was not bad for that parameter) or raise a csgnb
error (``PrecisionError``, ``GeometryError`` ...) or a ``TypeError`` with a message -- never a
raw ``AttributeError``, ``IndexError``, ``ZeroDivisionError``, ``KeyError``, ``OverflowError`` or
a ``ValueError`` from deep inside numpy. Functions are found by walking ``__all__`` and the
public methods of instances, so a new public function is covered without editing this file.
"""

from __future__ import annotations

import inspect
import warnings

import numpy as np
import pytest

from csgnb import CsgnbError, bsp, exact
from csgnb.bsp import BSP

BAD_VALUES = [
    5, -1, 2.7, None, "abc", 1 + 2j, float("nan"), [], [[1, 2]], np.zeros((2, 2)),
    np.full((3, 3), np.nan), np.zeros((0, 3)), np.array(["a", "b", "c"]), object(),
]

# Public functions that still raise raw errors on bad arguments. strict: the test fails once one
# is fixed, so the list only shrinks. Empty since the csgnb.bsp tree, polygon, extract, merging,
# random_tree and scenes modules validate their arguments.
KNOWN_RAW_ERRORS: set[str] = set()


def _bad_values():
    return BAD_VALUES + [exact.to_wide([1, 2], 128), exact.to_wide([[1, 0, 0, 1]], 192)]


def _public_callables():
    for mod in (exact, bsp):
        for name in mod.__all__:
            obj = getattr(mod, name)
            if callable(obj) and not isinstance(obj, type(np)):
                yield f"{mod.__name__}.{name}", obj
    instances = {
        "BSP()": BSP.box([0, 0, 0], [2, 2, 2]),
        "Grid()": exact.Grid.fit([0, 0, 0], [1, 1, 1]),
        "BitBudget()": exact.budget(128),
    }
    for label, inst in instances.items():
        for name, member in inspect.getmembers(inst, callable):
            if not name.startswith("_") and not isinstance(member, type):
                yield f"{label}.{name}", member
    box = instances["BSP()"]
    for name in ("__or__", "__and__", "__sub__", "__xor__"):
        yield f"BSP().{name}", getattr(box, name)


def _required_positional(f) -> int:
    try:
        sig = inspect.signature(f)
    except (TypeError, ValueError):
        return 1
    return sum(1 for p in sig.parameters.values()
               if p.default is p.empty and p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD))


def _raw_errors(f) -> list[str]:
    problems = []
    n = _required_positional(f)
    for value in _bad_values():
        for k in sorted({max(n, 1), 1}):
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    f(*([value] * k))
            except (CsgnbError, TypeError) as exc:
                if not str(exc).strip():
                    problems.append(f"{k} x {value!r:.30}: {type(exc).__name__} without a message")
            except FileNotFoundError:
                pass  # a string taken as a path that does not exist: the standard error for it
            except Exception as exc:  # noqa: BLE001 - the point is to catch everything else
                problems.append(f"{k} x {value!r:.30}: raw {type(exc).__name__}: {str(exc)[:80]}")
    return problems


CALLABLES = dict(_public_callables())


@pytest.mark.parametrize("name", sorted(CALLABLES))
def test_bad_arguments_get_clear_errors(name):
    if name in KNOWN_RAW_ERRORS:
        problems = _raw_errors(CALLABLES[name])
        if problems:
            pytest.xfail(f"{name}: argument checks not yet in this module ({len(problems)} raw errors)")
        pytest.fail(f"{name} is now clean: remove it from KNOWN_RAW_ERRORS")
    problems = _raw_errors(CALLABLES[name])
    assert not problems, f"{name}:\n" + "\n".join(problems)


def test_the_catalogue_covers_the_public_api():
    names = set(CALLABLES)
    for expected in ("csgnb.exact.to_wide", "csgnb.exact.classify_vertex", "csgnb.exact.quantize",
                     "csgnb.bsp.bsp_from_mesh", "BSP().merge", "BSP().to_width", "BSP().__or__", "Grid().to_grid"):
        assert expected in names
    assert len(names) > 50
