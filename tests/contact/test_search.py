"""Contact broad phase: exact agreement with the O(F G) oracle, edge cases, facing filter."""

import numpy as np
import pytest

from contopt.contact import search
from contopt.contact.search import (
    candidate_pairs,
    candidate_pairs_bruteforce,
    default_skin,
    facing_filter,
)
from contopt.mesh.generators import box


# ------------------------------------------------------------------- helpers
def rotation(rng):
    """A random proper rotation (3, 3)."""
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def rot_z(deg):
    a = np.radians(deg)
    return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])


def random_cloud(rng, n, extent=4.0, size_range=(0.02, 2.0), degenerate=0.1):
    """(n, 4, 3) warped quads, log-uniform sizes (100x), random orientation,
    a fraction collapsed to a point, a segment or a triangle."""
    sizes = np.exp(rng.uniform(*np.log(size_range), n))
    unit = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float) / 2
    local = unit + rng.uniform(-0.15, 0.15, (n, 4, 3))  # warped, not planar
    R = np.stack([rotation(rng) for _ in range(n)])
    x = np.einsum("nij,nkj->nki", R, local) * sizes[:, None, None]
    x += rng.uniform(0, extent, (n, 1, 3))
    kind = rng.integers(0, 3, n)
    deg = rng.random(n) < degenerate
    for f in np.nonzero(deg)[0]:
        if kind[f] == 0:
            x[f] = x[f, 0]  # a point
        elif kind[f] == 1:
            x[f, 2:] = x[f, 1]  # a segment
        else:
            x[f, 3] = x[f, 2]  # a triangle
    return x


def surface(mesh, name, rotation_=None, translation=None):
    m = mesh.transformed(rotation_, translation) if (rotation_ is not None or translation is not None) else mesh
    return m.points[m.facet_nodes(name)]


def check_exact(x_nm, x_m, skin):
    fast = candidate_pairs(x_nm, x_m, skin)
    ref = candidate_pairs_bruteforce(x_nm, x_m, skin)
    assert fast.dtype == np.int64 and fast.ndim == 2 and fast.shape[1] == 2
    missed = {tuple(p) for p in ref} - {tuple(p) for p in fast}
    extra = {tuple(p) for p in fast} - {tuple(p) for p in ref}
    assert not missed and not extra, f"missed {sorted(missed)[:5]}, extra {sorted(extra)[:5]}"
    np.testing.assert_array_equal(fast, ref)  # also order
    return fast


def loop_oracle(x_nm, x_m, skin):
    """Pure-Python restatement of the definition, independent of the module's helpers."""
    out = []
    for i, a in enumerate(x_nm):
        for j, b in enumerate(x_m):
            if all(
                a[:, k].min() - skin <= b[:, k].max() + skin and b[:, k].min() - skin <= a[:, k].max() + skin
                for k in range(3)
            ):
                out.append((i, j))
    return np.array(out, dtype=np.int64).reshape(-1, 2)


# --------------------------------------------------------- oracle agreement
@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("skin", [0.0, 0.03, 0.3])
def test_random_clouds_match_bruteforce(seed, skin):
    rng = np.random.default_rng(seed)
    x_nm = random_cloud(rng, 400)
    x_m = random_cloud(rng, 300, size_range=(0.01, 1.0)) + rng.uniform(-0.5, 0.5, 3)
    pairs = check_exact(x_nm, x_m, skin)
    # the test is only meaningful with many pairs, spread over several size classes
    assert len(pairs) > 300
    assert len(search._size_classes(0.5 * (x_nm.max(1) - x_nm.min(1)).max(1))) >= 5


def test_bruteforce_matches_definition(rng):
    x_nm = random_cloud(rng, 40, extent=2.0)
    x_m = random_cloud(rng, 30, extent=2.0)
    for skin in (0.0, 0.1):
        ref = loop_oracle(x_nm, x_m, skin)
        assert len(ref) > 20
        np.testing.assert_array_equal(candidate_pairs_bruteforce(x_nm, x_m, skin), ref)
        np.testing.assert_array_equal(candidate_pairs(x_nm, x_m, skin), ref)


def test_hand_checked_gap_and_touching():
    sq = np.array([[[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]], float)
    for gap, skin, expect in [(0.0, 0.0, 1), (0.2, 0.1, 1), (0.2, 0.0999, 0), (0.5, 0.0, 0)]:
        other = (sq + [0, 0, gap])[:, ::-1]
        assert len(candidate_pairs(sq, other, skin)) == expect
        assert len(candidate_pairs_bruteforce(sq, other, skin)) == expect
    # edge-adjacent in-plane squares touch at skin 0
    np.testing.assert_array_equal(candidate_pairs(sq, sq + [1, 0, 0], 0.0), [[0, 0]])
    assert len(candidate_pairs(sq, sq + [1 + 1e-9, 0, 0], 0.0)) == 0


@pytest.mark.parametrize("skin", [0.0, 0.01])
@pytest.mark.parametrize(
    "shift, angle",
    [
        ((0.0, 0.0), 0.0),
        ((0.37, 0.11), 0.0),
        ((0.8, -0.6), 0.0),
        ((0.25, 0.1), 30.0),
        ((1.3, 0.0), 0.0),
        ((-2.0, 0.45), 17.0),
    ],
)
def test_structured_meshes_large_sliding(shift, angle, skin):
    # slab top (normal +z) against the bottom of a finer, shifted and turned block (normal -z)
    slab = box((1.0, 1.0, 0.2), (12, 10, 2), origin=(0, 0, -0.2))
    die = box((0.8, 0.7, 0.3), (17, 13, 1), origin=(-0.4, -0.35, 0.0))
    x_nm = surface(slab, "zmax")
    x_m = surface(die, "zmin", rot_z(angle), [0.5 + shift[0], 0.5 + shift[1], 0.0])
    pairs = check_exact(x_nm, x_m, skin)
    if max(abs(shift[0]), abs(shift[1])) < 0.5:
        assert len(pairs) > len(x_m)
    elif max(abs(shift[0]), abs(shift[1])) < 0.9:
        assert len(pairs) > 0


def test_structured_matching_meshes_touching_nodes():
    # coincident conforming surfaces: every facet touches its 8 neighbours at skin 0
    slab = box((1.0, 1.0, 0.2), (8, 8, 1), origin=(0, 0, -0.2))
    top = box((1.0, 1.0, 0.2), (8, 8, 1), origin=(0, 0, 0.0))
    pairs = check_exact(surface(slab, "zmax"), surface(top, "zmin"), 0.0)
    assert len(pairs) == 64 * 9 - 4 * 8 * 3 + 4  # 3x3 stencil clipped at the 4 borders


def test_die_facets_ten_times_larger():
    # a coarse die (facets ~10x the slab's) with a curved, tilted bottom
    slab = box((2.0, 2.0, 0.2), (60, 60, 1), origin=(0, 0, -0.2))
    die = box((1.2, 1.2, 0.5), (4, 4, 1), origin=(0.33, 0.41, 0.0))
    x_m = surface(die, "zmin")
    r = x_m[..., :2] - [0.93, 1.01]
    x_m[..., 2] = -0.01 + 0.05 * (r**2).sum(-1)  # penetrating, curved
    tilt = np.array([[1, 0, 0], [0, np.cos(0.1), -np.sin(0.1)], [0, np.sin(0.1), np.cos(0.1)]])
    x_m = (x_m - [0.93, 1.01, 0]) @ tilt.T + [0.93, 1.01, 0]  # tilted about the die centre
    x_nm = surface(slab, "zmax")
    for skin in (0.0, default_skin(x_nm, x_m)):
        pairs = check_exact(x_nm, x_m, skin)
        assert len(pairs) > 200
        pairs_rev = check_exact(x_m, x_nm, skin)  # the coarse side as nonmortar
        swapped = pairs_rev[:, ::-1]
        np.testing.assert_array_equal(swapped[np.lexsort(swapped.T[::-1])], pairs)


def test_single_huge_facet_among_small(rng):
    slab = box((1.0, 1.0, 0.2), (30, 30, 1), origin=(0, 0, -0.2))
    x_nm = surface(slab, "zmax")
    huge = np.array([[[0.2, -0.5, 0.05], [0.2, 1.5, 0.05], [1.8, 1.5, -0.3], [1.8, -0.5, -0.3]]])
    small = random_cloud(rng, 200, extent=1.0, size_range=(0.01, 0.05)) + [0, 0, -0.5]
    x_m = np.concatenate([small, huge])
    pairs = check_exact(x_nm, x_m, 0.002)
    assert np.count_nonzero(pairs[:, 1] == len(x_m) - 1) > 300
    # the huge facet has a class of its own, so the small ones keep a small query radius
    h = 0.5 * (x_m.max(1) - x_m.min(1)).max(1)
    classes = search._size_classes(h)
    assert any(np.array_equal(c, [len(x_m) - 1]) for c in classes)


def test_far_apart_and_empty_inputs():
    sq = np.array([[[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]], float)
    assert candidate_pairs(sq, sq + 10.0, 1.0).shape == (0, 2)
    empty = np.zeros((0, 4, 3))
    for a, b in [(empty, sq), (sq, empty), (empty, empty), ([], sq)]:
        for f in (candidate_pairs, candidate_pairs_bruteforce):
            out = f(a, b, 0.1)
            assert out.shape == (0, 2) and out.dtype == np.int64
    assert default_skin(empty, empty) == 0.0
    assert default_skin(empty, sq) == pytest.approx(0.2)
    assert facing_filter(sq, sq, np.zeros((0, 2), int)).shape == (0, 2)


def test_all_degenerate_points_skin_zero():
    pts = np.repeat(np.array([[0.0, 0, 0], [1, 0, 0], [1, 0, 0], [2, 2, 2]])[:, None], 4, axis=1)
    np.testing.assert_array_equal(candidate_pairs(pts, pts, 0.0), [[0, 0], [1, 1], [1, 2], [2, 1], [2, 2], [3, 3]])
    zero = np.zeros((3, 4, 3))  # everything at one point: zero query radius, all pairs touch
    assert len(candidate_pairs(zero, zero, 0.0)) == 9


def test_far_from_origin_touching_pairs_kept():
    # round-off in the box centres is relative to the coordinates, not to the
    # facet size: without padding the query radius, some of these touching
    # neighbours are lost
    rng = np.random.default_rng(0)
    for _ in range(20):
        origin, size = rng.uniform(-1e4, 1e4, 3), rng.uniform(1e-4, 1e-2)
        slab = box((size, 1.3 * size, size / 10), (9, 7, 1), origin=origin)
        x = surface(slab, "zmax")
        pairs = check_exact(x, x[:, ::-1], 0.0)  # the same surface, facing: a 3x3 stencil each
        assert len(pairs) == 63 * 9 - 2 * (9 + 7) * 3 + 4


def test_bad_input():
    sq = np.zeros((1, 4, 3))
    with pytest.raises(ValueError, match="shape"):
        candidate_pairs(np.zeros((2, 3, 3)), sq, 0.0)
    with pytest.raises(ValueError, match="skin"):
        candidate_pairs(sq, sq, -1.0)
    with pytest.raises(ValueError, match="non-finite"):
        candidate_pairs(np.full((1, 4, 3), np.nan), sq, 0.0)


def test_2000_by_2000_finishes():
    slab = box((1.0, 1.0, 0.2), (50, 40, 1), origin=(0, 0, -0.2))
    die = box((1.0, 1.0, 0.2), (40, 50, 1), origin=(0.31, -0.17, 0.0))
    x_nm, x_m = surface(slab, "zmax"), surface(die, "zmin")
    assert len(x_nm) == len(x_m) == 2000
    check_exact(x_nm, x_m, default_skin(x_nm, x_m))


# -------------------------------------------------------------- default skin
def test_default_skin_is_fraction_of_finer_side():
    fine = box((1.0, 1.0, 0.2), (20, 20, 1), origin=(0, 0, -0.2))
    coarse = box((1.0, 1.0, 0.2), (4, 4, 1))
    s = default_skin(surface(fine, "zmax"), surface(coarse, "zmin"))
    assert s == pytest.approx(0.2 * 0.05)
    assert default_skin(surface(coarse, "zmin"), surface(fine, "zmax")) == pytest.approx(s)


# ------------------------------------------------------------- facing filter
def _facing_setup(angle_deg=0.0, gap=0.0):
    slab = box((1.0, 1.0, 0.2), (6, 6, 1), origin=(0, 0, -0.2))
    die = box((0.6, 0.6, 0.2), (3, 3, 1), origin=(-0.3, -0.3, 0.0))
    a = np.radians(angle_deg)
    tilt = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
    x_nm = surface(slab, "zmax")
    x_m = surface(die, "zmin", tilt, [0.5, 0.5, gap])
    return x_nm, x_m


def test_facing_filter_keeps_facing_and_drops_same_direction():
    x_nm, x_m = _facing_setup()
    pairs = candidate_pairs(x_nm, x_m, 0.05)
    assert len(pairs) > 0
    np.testing.assert_array_equal(facing_filter(x_nm, x_m, pairs, 75.0, 0.05), pairs)
    # the die's top face points the same way as the slab's top: never in contact
    die_top = x_m[:, ::-1]  # reversed node order flips the normal
    assert facing_filter(x_nm, die_top, pairs, 90.0, 0.05).shape == (0, 2)


@pytest.mark.parametrize(
    "tilt, max_angle, kept", [(30.0, 45.0, True), (30.0, 25.0, False), (60.0, 75.0, True), (60.0, 50.0, False)]
)
def test_facing_filter_angle(tilt, max_angle, kept):
    x_nm, x_m = _facing_setup(tilt)
    pairs = candidate_pairs(x_nm, x_m, 0.05)
    assert len(pairs) > 0
    out = facing_filter(x_nm, x_m, pairs, max_angle, 0.05)
    assert len(out) == (len(pairs) if kept else 0)


def test_facing_filter_drops_far_behind_and_keeps_moderate_penetration():
    sq_up = np.array([[[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]], float)  # normal +z
    sq_down = sq_up[:, ::-1]  # normal -z
    skin, r = 0.1, np.sqrt(0.5)  # r: corner distance from the centre of the unit square
    pairs = np.array([[0, 0]])
    for depth, kept in [
        (0.05, True),
        (0.5, True),
        (skin + 2 * r - 1e-6, True),
        (skin + 2 * r + 1e-6, False),
        (3.0, False),
        (-5.0, True),
    ]:
        out = facing_filter(sq_up, sq_down - [0, 0, depth], pairs, 75.0, skin)
        assert len(out) == int(kept), depth
    # the allowance adds both facets' sizes: a small nonmortar facet under a large mortar one
    small_up = 0.1 * sq_up + 0.45
    for depth, kept in [(skin + 1.1 * r - 1e-6, True), (skin + 1.1 * r + 1e-6, False)]:
        assert len(facing_filter(small_up, sq_down + 0.45 - [0, 0, depth], pairs, 75.0, skin)) == int(kept)


def test_facing_filter_never_drops_touching_pairs(rng):
    # property behind rule (b): whenever some point of the mortar facet is within skin of
    # the nonmortar facet, the pair stays, whatever the shapes (warped, trapezoids, slivers)
    skin = 0.05
    x_nm = random_cloud(rng, 300, extent=0.0, size_range=(0.1, 1.0), degenerate=0.0)
    x_m = random_cloud(rng, 300, extent=0.0, size_range=(0.1, 1.0), degenerate=0.0)
    x_m[:, 1] += rng.uniform(0, 3, (300, 1)) * (x_m[:, 1] - x_m[:, 0])  # long edges: trapezoid-like
    # move a random mortar node onto a random nonmortar point, then off it by < skin
    u, v = rng.random((2, 300, 1))
    p = (1 - u) * ((1 - v) * x_nm[:, 0] + v * x_nm[:, 3]) + u * ((1 - v) * x_nm[:, 1] + v * x_nm[:, 2])
    k = rng.integers(0, 4, 300)
    offset = rng.normal(size=(300, 3))
    offset *= 0.99 * skin * rng.random((300, 1)) / np.linalg.norm(offset, axis=1, keepdims=True)
    x_m += (p + offset - x_m[np.arange(300), k])[:, None]
    pairs = np.stack([np.arange(300), np.arange(300)], axis=1)
    np.testing.assert_array_equal(facing_filter(x_nm, x_m, pairs, 180.0, skin), pairs)
    # and the rule is not vacuous: pushed 3 facet sizes behind, most are dropped
    n = search._area_vectors(x_nm)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    deep = x_m - 3.0 * n[:, None]
    assert len(facing_filter(x_nm, deep, pairs, 180.0, skin)) < 150


def test_facing_filter_keeps_degenerate_and_order():
    x_nm, x_m = _facing_setup()
    x_m = x_m.copy()
    x_m[4] = x_m[4, 0]  # a facet collapsed to a point: no normal, cannot be judged
    pairs = candidate_pairs(x_nm, x_m, 0.05)
    rev = pairs[::-1]
    out = facing_filter(x_nm, x_m[:, ::-1], rev, 75.0, 0.05)  # all others point the same way
    assert len(out) > 0 and np.all(out[:, 1] == 4)
    assert np.all(np.diff(out[:, 0]) <= 0)  # original (reversed) order kept
    with pytest.raises(ValueError):
        facing_filter(x_nm, x_m, [[0, len(x_m)]], 75.0, 0.05)
