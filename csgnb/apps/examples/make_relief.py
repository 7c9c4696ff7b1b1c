"""Write relief.nc: a ball end mill finishing a smooth 3-D relief by raster passes.

``python -m csgnb.apps.examples.make_relief`` rewrites ``relief.nc`` next to this file.

The tip follows the height field z(x, y) below, row by row along X (zig-zag), rows 3 mm
apart, points 3 mm apart along a row: shaped like a real finishing pass, small enough for
the single-BSP reference workpiece the tests compare the octree with.
"""

import math
from pathlib import Path


def height(x: float, y: float) -> float:
    """Depth of the relief under the tool tip (mm, z = 0 is the stock top)."""
    bump = 1.2 * math.exp(-((x - 20) ** 2 + (y - 15) ** 2) / 60)
    return round(-3.0 + 1.0 * math.sin(x / 5) * math.cos(y / 6) + bump, 3)


def program() -> str:
    """The text of relief.nc."""
    out = [
        "%",
        "(relief.nc -- a 3-D relief finished with a ball end mill, written by csgnb/apps/examples/make_relief.py)",
        "(stock: 40 x 30 x 8 mm, origin at the lower left corner of the top face, z = 0 on top)",
        "(tool: T1, 4 mm ball end mill; run: python -m csgnb.mill csgnb/apps/examples/relief.nc --stock 40 30 8 "
        "--tool ball:4 --segments 16)",
        "G21 G90 G17 G94",
        "T1 M6",
        "S16000 M3",
        "G0 Z5",
    ]
    xs = [2.0 + 3.0 * i for i in range(13)]
    for row, y in enumerate(3.0 + 3.0 * j for j in range(9)):
        line = xs if row % 2 == 0 else xs[::-1]
        out.append(f"G0 X{line[0]:g} Y{y:g}" if row == 0 else f"G1 Y{y:g} Z{height(line[0], y):g} F800")
        if row == 0:
            out.append(f"G1 Z{height(line[0], y):g} F200")
        for x in line[1:]:
            out.append(f"G1 X{x:g} Z{height(x, y):g} F1200")
    out += ["G0 Z5", "M5", "G0 X0 Y0 Z20", "M30", "%"]
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    Path(__file__).with_name("relief.nc").write_text(program())
