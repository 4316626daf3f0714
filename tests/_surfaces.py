"""Checks of closed triangle surfaces written independently of ``contopt.io.surface.check_surface``
(plain Python dictionaries and walks instead of its sorted-array counting)."""

from collections import Counter, defaultdict

import numpy as np


def signed_volume(vertices, faces) -> float:
    """Divergence theorem: sum over faces of det(a, b, c) / 6."""
    v = np.asarray(vertices, dtype=np.float64)
    return float(sum(np.linalg.det(v[list(f)]) for f in np.asarray(faces)) / 6.0)


def closed_manifold_problems(vertices, faces) -> list[str]:
    """What keeps (vertices, faces) from being a closed, consistently oriented 2-manifold; [] if nothing.

    * watertight and oriented: every directed edge occurs once and its reverse once (so every
      undirected edge is in exactly two faces, which run through it in opposite directions);
    * manifold vertices: walking from face to face around a vertex (across the edge into it)
      visits all of the vertex's faces in one loop;
    * no face with a repeated vertex; outward normals: positive signed volume.
    """
    faces = [tuple(int(i) for i in f) for f in np.asarray(faces)]
    problems = []
    if not faces:
        return ["no faces"]
    if any(len(set(f)) < 3 for f in faces):
        problems.append("face with a repeated vertex")
    directed = Counter((f[k], f[(k + 1) % 3]) for f in faces for k in range(3))
    if any(n != 1 for n in directed.values()):
        problems.append("a directed edge in more than one face (non-manifold or inconsistent orientation)")
    missing = [e for e in directed if (e[1], e[0]) not in directed]
    if missing:
        problems.append(f"{len(missing)} edges without an opposite half-edge (open or inconsistently oriented)")
    if problems:
        return problems
    # the face that holds the directed edge v -> w
    owner = {(f[k], f[(k + 1) % 3]): f for f in faces for k in range(3)}
    around = defaultdict(list)
    for f in faces:
        for v in f:
            around[v].append(f)
    for v, fs in around.items():
        start = fs[0]
        seen, f = set(), start
        while f not in seen:
            seen.add(f)
            k = f.index(v)
            prev = f[(k + 2) % 3]  # f = (v, a, prev): the next face around v holds v -> prev
            f = owner[(v, prev)]
        if len(seen) != len(fs):
            problems.append(f"vertex {v}: its faces form more than one fan")
            break
    if signed_volume(vertices, faces) <= 0:
        problems.append("normals point inward")
    return problems
