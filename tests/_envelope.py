"""A bracket-like closed surface for the voxel tests: an L-shaped prism with a 45-degree gusset."""

import numpy as np

from contopt.io.surface import TriangleSurface, write_surface

#: the bracket's profile in the x-z plane (counter-clockwise; star-shaped about its first corner)
PROFILE = np.array([(0.0, 0.0), (2.0, 0.0), (2.0, 0.4), (1.0, 0.4), (0.4, 1.0), (0.4, 2.0), (0.0, 2.0)])
#: its extent in y
DEPTH = 0.8


def profile_area() -> float:
    x, z = PROFILE.T
    return 0.5 * float(np.sum(x * np.roll(z, -1) - np.roll(x, -1) * z))


def bracket(profile=PROFILE, depth=DEPTH, origin=(0.0, 0.0, 0.0)) -> TriangleSurface:
    """The prism of ``profile`` (x, z) over y in [0, depth], outward triangles, shifted by ``origin``."""
    n = len(profile)
    front = np.column_stack([profile[:, 0], np.zeros(n), profile[:, 1]])  # y = 0
    back = front + [0.0, depth, 0.0]
    vertices = np.vstack([front, back]) + np.asarray(origin)
    faces = []
    for i in range(1, n - 1):  # the caps: fans from corner 0
        faces.append([0, i, i + 1])  # y = 0 faces -y: (x, z) counter-clockwise is clockwise seen from -y
        faces.append([n, n + i + 1, n + i])
    for i in range(n):  # the sides
        j = (i + 1) % n
        faces += [[i, n + i, n + j], [i, n + j, j]]
    return TriangleSurface(vertices, np.array(faces))


def write_bracket(path, **kw):
    write_surface(bracket(**kw), path)
    return path
