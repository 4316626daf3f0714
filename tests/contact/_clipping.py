"""An independent oracle for the mortar tests: plain Sutherland-Hodgman clipping of convex polygons."""

import numpy as np


def clipped_area(subject, clip):
    """Area of the intersection of two convex counter-clockwise polygons (plain Sutherland-Hodgman)."""
    poly = list(subject)
    for k in range(len(clip)):
        e0, e1 = clip[k], clip[(k + 1) % len(clip)]
        side = [(e1 - e0)[0] * (p - e0)[1] - (e1 - e0)[1] * (p - e0)[0] for p in poly]
        new = []
        for i in range(len(poly)):
            p, q, sp, sq = poly[i], poly[(i + 1) % len(poly)], side[i], side[(i + 1) % len(poly)]
            if sp >= 0:
                new.append(p)
            if (sp >= 0) != (sq >= 0):
                new.append(p + sp / (sp - sq) * (q - p))
        poly = new
        if not poly:
            return 0.0
    x, y = np.array(poly).T
    return 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)
