"""The G-code programs shipped with csgnb, as package data: found from anywhere, a notebook copy or a wheel.

>>> from csgnb.apps.examples import EXAMPLES, example_path
>>> sorted(EXAMPLES)
['pocket.nc', 'relief.nc', 'subroutines.nc']
>>> example_path("pocket.nc").name
'pocket.nc'

* ``pocket.nc``: a rounded 24 x 16 mm pocket 4 mm deep in two steps and an outside contour,
  6 mm flat end mill, stock 50 x 40 x 10 mm;
* ``relief.nc``: a smooth 3-D relief by zig-zag raster passes with a 4 mm ball end mill,
  stock 40 x 30 x 8 mm, written by :mod:`csgnb.apps.examples.make_relief`;
* ``subroutines.nc``: three round pockets by one O-word subroutine called in a loop, with
  parameters, expressions and ``G10 L2`` -- written in the style of a hand-written LinuxCNC
  program; 3 mm flat end mill, stock 50 x 20 x 5 mm.

Each program's stock is ``[0, X] x [0, Y] x [-Z, 0]`` (origin at the lower left corner of the
top face), as ``python -m csgnb.mill`` sets it up.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

__all__ = ["EXAMPLES", "Example", "example_path", "example_program"]

_HERE = Path(__file__).resolve().parent


@dataclass(frozen=True)
class Example:
    """How a shipped program is meant to run: stock size (mm) and the tool spec of ``python -m csgnb.mill``."""

    name: str
    stock: tuple[float, float, float]
    tool: str
    description: str
    segments: int | None = None

    @property
    def path(self) -> Path:
        """The program file."""
        return example_path(self.name)

    def cli_args(self) -> list[str]:
        """``python -m csgnb.mill`` arguments for this program (without ``--out``)."""
        args = [str(self.path), "--stock", *(f"{x:g}" for x in self.stock), "--tool", self.tool]
        return args + (["--segments", str(self.segments)] if self.segments else [])


EXAMPLES: dict[str, Example] = {
    "pocket.nc": Example("pocket.nc", (50.0, 40.0, 10.0), "flat:6",
                         "a rounded pocket in two depth steps and an outside contour (6 mm flat end mill)"),
    "relief.nc": Example("relief.nc", (40.0, 30.0, 8.0), "ball:4",
                         "a 3-D relief by raster passes (4 mm ball end mill)", segments=16),
    "subroutines.nc": Example("subroutines.nc", (50.0, 20.0, 5.0), "flat:3",
                              "three round pockets by a LinuxCNC subroutine in a loop (3 mm flat end mill)"),
}
"""The shipped programs by file name."""


def example_path(name: str) -> Path:
    """The path of the shipped program ``name`` (a key of :data:`EXAMPLES`; the ``.nc`` may be left off)."""
    key = name if name.endswith(".nc") else f"{name}.nc"
    if key not in EXAMPLES:
        raise KeyError(f"no shipped G-code program {name!r}; the examples are {sorted(EXAMPLES)}")
    return _HERE / key


def example_program(name: str, **kw):
    """The shipped program ``name`` parsed by :func:`csgnb.apps.gcode.parse_file` (keywords go to it)."""
    from csgnb.apps.gcode import parse_file

    return parse_file(example_path(name), **kw)
