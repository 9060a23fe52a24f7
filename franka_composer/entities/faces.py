"""Six distinctly coloured faces on a cube, so its orientation can be told apart in images.

Thin box sites just outside each face: sites render but have no mass and never collide, so
the cube's physics is a plain box's.
"""

from __future__ import annotations

#: Face colours for +x, -x, +y, -y, +z, -z: red, cyan, green, magenta, blue, yellow
#: (opposite faces complementary).
FACE_COLOURS = ((0.9, 0.15, 0.15), (0.15, 0.85, 0.85), (0.15, 0.75, 0.2),
                (0.8, 0.2, 0.8), (0.15, 0.3, 0.9), (0.95, 0.85, 0.15))
#: Thickness (m) of a face plate, and how much of a face it covers.
_THICKNESS = 0.0008
_COVER = 0.8


def add_coloured_faces(body, half_size: float, alpha: float = 1.0, group: int = 0) -> list:
    """Adds the six face plates to `body` (an MJCF body or worldbody centred on a cube of
    `half_size`); returns the sites."""
    sites = []
    for index, rgb in enumerate(FACE_COLOURS):
        axis, sign = divmod(index, 2)
        pos = [0.0, 0.0, 0.0]
        pos[axis] = (half_size + _THICKNESS) * (1 if sign == 0 else -1)
        size = [half_size * _COVER] * 3
        size[axis] = _THICKNESS
        sites.append(body.add("site", name=f"face{index}", type="box", pos=pos, size=size,
                              rgba=(*rgb, alpha), group=group))
    return sites
