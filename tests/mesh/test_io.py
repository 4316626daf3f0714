"""Mesh files: exact round trips through .msh (4.1, 2.2), .vtu and Exodus, files
written by Gmsh itself, several bodies per file, and the error messages."""

import importlib.util
import struct

import meshio
import numpy as np
import pytest

from contopt.errors import MeshError
from contopt.mesh import (
    Mesh,
    annulus,
    box,
    cylinder,
    cylinder_shell_sector,
    read_bodies,
    read_mesh,
    write_mesh,
)

HAVE_NETCDF4 = importlib.util.find_spec("netCDF4") is not None
needs_netcdf4 = pytest.mark.skipif(
    not HAVE_NETCDF4, reason="Exodus I/O needs the optional package netCDF4 (pip install netCDF4)"
)

# A 2 x 1 x 1 block meshed with 3 hexahedra by Gmsh 4.15 (transfinite,
# recombined), saved in ASCII MSH 4.1 and 2.2, with physical groups
# "block" (volume), "top" (z = 1) and "xmin" (x = 0) surfaces, "z_edge"
# (the curve x = y = 0) and "origin" (the point 0, 0, 0).
GMSH_41 = """$MeshFormat
4.1 0 8
$EndMeshFormat
$PhysicalNames
5
0 5 "origin"
1 4 "z_edge"
2 2 "top"
2 3 "xmin"
3 1 "block"
$EndPhysicalNames
$Entities
8 12 6 1
1 0 0 1 0
2 0 0 0 1 5
3 0 1 1 0
4 0 1 0 0
5 2 0 1 0
6 2 0 0 0
7 2 1 1 0
8 2 1 0 0
1 -1e-07 -1e-07 -9.999999994736442e-08 1e-07 1e-07 1.0000001 1 4 2 2 -1
2 -1e-07 -9.999999994736442e-08 0.9999999000000001 1e-07 1.0000001 1.0000001 0 2 1 -3
3 -1e-07 0.9999999000000001 -9.999999994736442e-08 1e-07 1.0000001 1.0000001 0 2 4 -3
4 -1e-07 -9.999999994736442e-08 -1e-07 1e-07 1.0000001 1e-07 0 2 2 -4
5 1.9999999 -1e-07 -9.999999994736442e-08 2.0000001 1e-07 1.0000001 0 2 6 -5
6 1.9999999 -9.999999994736442e-08 0.9999999000000001 2.0000001 1.0000001 1.0000001 0 2 5 -7
7 1.9999999 0.9999999000000001 -9.999999994736442e-08 2.0000001 1.0000001 1.0000001 0 2 8 -7
8 1.9999999 -9.999999994736442e-08 -1e-07 2.0000001 1.0000001 1e-07 0 2 6 -8
9 -9.999999994736442e-08 -1e-07 -1e-07 2.0000001 1e-07 1e-07 0 2 2 -6
10 -9.999999994736442e-08 -1e-07 0.9999999000000001 2.0000001 1e-07 1.0000001 0 2 1 -5
11 -9.999999994736442e-08 0.9999999000000001 -1e-07 2.0000001 1.0000001 1e-07 0 2 4 -8
12 -9.999999994736442e-08 0.9999999000000001 0.9999999000000001 2.0000001 1.0000001 1.0000001 0 2 3 -7
1 -1e-07 -9.999999994736442e-08 -9.999999994736442e-08 1e-07 1.0000001 1.0000001 1 3 4 -1 4 3 -2
2 1.9999999 -9.999999994736442e-08 -9.999999994736442e-08 2.0000001 1.0000001 1.0000001 0 4 -5 8 7 -6
3 -9.999999994736442e-08 -1e-07 -9.999999994736442e-08 2.0000001 1e-07 1.0000001 0 4 -9 1 10 -5
4 -9.999999994736442e-08 0.9999999000000001 -9.999999994736442e-08 2.0000001 1.0000001 1.0000001 0 4 -11 3 12 -7
5 -9.999999994736442e-08 -9.999999994736442e-08 -1e-07 2.0000001 1.0000001 1e-07 0 4 -4 9 8 -11
6 -9.999999994736442e-08 -9.999999994736442e-08 0.9999999000000001 2.0000001 1.0000001 1.0000001 1 2 4 -2 10 6 -12
1 -9.999999994736442e-08 -9.999999994736442e-08 -9.999999994736442e-08 2.0000001 1.0000001 1.0000001 1 1 6 -1 2 -3 4 -5 6
$EndEntities
$Nodes
16 16 1 16
0 1 0 1
1
0 0 1
0 2 0 1
2
0 0 0
0 3 0 1
3
0 1 1
0 4 0 1
4
0 1 0
0 5 0 1
5
2 0 1
0 6 0 1
6
2 0 0
0 7 0 1
7
2 1 1
0 8 0 1
8
2 1 0
1 1 0 0
1 9 0 2
9
10
0.6666666666666666 0 0
1.333333333333333 0 0
1 10 0 2
11
12
0.6666666666666666 0 1
1.333333333333333 0 1
1 11 0 2
13
14
0.6666666666666666 1 0
1.333333333333333 1 0
1 12 0 2
15
16
0.6666666666666666 1 1
1.333333333333333 1 1
2 1 0 0
2 6 0 0
3 1 0 0
$EndNodes
$Elements
5 9 1 9
0 2 15 1
1 2
1 1 1 1
2 2 1
2 1 3 1
3 2 1 3 4
2 6 3 3
4 1 11 15 3
5 11 12 16 15
6 12 5 7 16
3 1 5 3
7 3 1 2 4 15 11 9 13
8 15 11 9 13 16 12 10 14
9 16 12 10 14 7 5 6 8
$EndElements
"""

GMSH_22 = """$MeshFormat
2.2 0 8
$EndMeshFormat
$PhysicalNames
5
0 5 "origin"
1 4 "z_edge"
2 2 "top"
2 3 "xmin"
3 1 "block"
$EndPhysicalNames
$Nodes
16
1 0 0 1
2 0 0 0
3 0 1 1
4 0 1 0
5 2 0 1
6 2 0 0
7 2 1 1
8 2 1 0
9 0.6666666666666666 0 0
10 1.333333333333333 0 0
11 0.6666666666666666 0 1
12 1.333333333333333 0 1
13 0.6666666666666666 1 0
14 1.333333333333333 1 0
15 0.6666666666666666 1 1
16 1.333333333333333 1 1
$EndNodes
$Elements
9
1 15 2 5 2 2
2 1 2 4 1 2 1
3 3 2 3 1 2 1 3 4
4 3 2 2 6 1 11 15 3
5 3 2 2 6 11 12 16 15
6 3 2 2 6 12 5 7 16
7 5 2 1 1 3 1 2 4 15 11 9 13
8 5 2 1 1 15 11 9 13 16 12 10 14
9 5 2 1 1 16 12 10 14 7 5 6 8
$EndElements
"""


# ------------------------------------------------------------------- helpers
def assert_same_mesh(a: Mesh, b: Mesh):
    """Points and cells exactly equal; sets equal as sets of rows."""
    assert a.points.dtype == b.points.dtype == np.float64
    assert np.array_equal(a.points, b.points)
    assert np.array_equal(a.cells, b.cells)
    assert sorted(a.node_sets) == sorted(b.node_sets)
    assert sorted(a.facet_sets) == sorted(b.facet_sets)
    for name in a.node_sets:
        assert set(a.node_sets[name].tolist()) == set(b.node_sets[name].tolist()), name
    for name in a.facet_sets:
        fa = set(map(tuple, a.facet_sets[name].tolist()))
        fb = set(map(tuple, b.facet_sets[name].tolist()))
        assert fa == fb, name
        assert len(fa) == len(a.facet_sets[name]) == len(b.facet_sets[name]), name


def rich_box():
    """A box with overlapping facet sets, an empty facet set and extra node sets."""
    mesh = box((1.0, 0.7, 0.3), (3, 2, 2), origin=(0.1, 0.2, 0.3), grading=(2.0, None, None))
    zmax = mesh.facet_set("zmax")
    contact = zmax[:3]  # a part of zmax: the same faces are in two sets
    contact_nodes = np.unique(mesh.facet_nodes(contact))
    return mesh.with_sets(
        node_sets={"contact": contact_nodes, "corner": [0], "empty_nodes": np.zeros(0, int)},
        facet_sets={"contact": contact, "empty": np.zeros((0, 2), int)},
    ).with_sets(node_sets={"empty": np.zeros(0, int)})


MESHES = {
    "box": rich_box,
    "ring": lambda: annulus(0.5, 1.0, 0.4, (8, 2, 1)),
    "cylinder": lambda: cylinder(1.0, 2.0, (2, 1, 2), center=(0.1, 0.2, 0.3)),
    "shell": lambda: cylinder_shell_sector(2.0, 0.9, 0.5, 0.1, (6, 2, 1), center=(0, 0, 2.05)),
}

FORMATS = {
    "msh41-binary": (".msh", dict(file_format="gmsh", binary=True)),
    "msh41-ascii": (".msh", dict(file_format="gmsh", binary=False)),
    "msh22-binary": (".msh", dict(file_format="gmsh22", binary=True)),
    "msh22-ascii": (".msh", dict(file_format="gmsh22", binary=False)),
    "vtu": (".vtu", {}),
    "exodus": (".exo", {}),
}


# ---------------------------------------------------------------- round trips
@pytest.mark.parametrize("fmt", list(FORMATS))
@pytest.mark.parametrize("which", list(MESHES))
def test_round_trip_is_exact(tmp_path, fmt, which):
    suffix, kwargs = FORMATS[fmt]
    if fmt == "exodus" and not HAVE_NETCDF4:
        pytest.skip("Exodus I/O needs the optional package netCDF4 (pip install netCDF4)")
    mesh = MESHES[which]()
    path = tmp_path / f"mesh{suffix}"
    write_mesh(path, mesh, **kwargs)
    back = read_mesh(path)
    if fmt == "exodus":
        # Exodus keeps empty side sets but, written through meshio, no empty node sets
        mesh = Mesh(mesh.points, mesh.cells, {k: v for k, v in mesh.node_sets.items() if len(v)}, mesh.facet_sets)
    assert_same_mesh(mesh, back)


def test_msh_reading_adds_node_sets_for_facet_groups_vtu_does_not(tmp_path):
    base = box((1, 1, 1), (2, 2, 2))
    mesh = Mesh(base.points, base.cells, {"fixed": [0, 1]}, {"top": base.facet_set("zmax")})
    write_mesh(tmp_path / "m.msh", mesh)
    write_mesh(tmp_path / "m.vtu", mesh)
    from_msh = read_mesh(tmp_path / "m.msh")
    assert sorted(from_msh.node_sets) == ["fixed", "top"]
    assert np.array_equal(from_msh.node_sets["top"], base.node_sets["zmax"])
    assert sorted(read_mesh(tmp_path / "m.msh", facet_node_sets=False).node_sets) == ["fixed"]
    assert_same_mesh(mesh, read_mesh(tmp_path / "m.vtu"))
    assert sorted(read_mesh(tmp_path / "m.vtu", facet_node_sets=True).node_sets) == ["fixed", "top"]


def test_msh_files_open_as_gmsh_physical_groups(tmp_path):
    """What meshio (independently of our reader) sees in a written .msh."""
    mesh = box((1, 1, 1), (1, 1, 2)).with_sets(node_sets={"corner": [0, 5]})
    for fmt in ("gmsh", "gmsh22"):
        path = tmp_path / f"{fmt}.msh"
        write_mesh(path, mesh, file_format=fmt, body_name="slab")
        m = meshio.read(path)
        names = {k: tuple(int(x) for x in v) for k, v in m.field_data.items()}
        assert names["slab"][1] == 3 and names["zmax"][1] == 2 and names["corner"][1] == 0
        assert "all" in names and names["all"][1] == 0
        assert "xmin" in names and names["xmin"][1] == 2
        types = [c.type for c in m.cells]
        assert types.count("hexahedron") == 1 and "quad" in types and "vertex" in types


def test_vtu_membership_arrays(tmp_path):
    mesh = rich_box()
    path = tmp_path / "m.vtu"
    write_mesh(path, mesh)
    m = meshio.read(path)
    assert [c.type for c in m.cells] == ["hexahedron", "quad"]
    union = np.unique(np.concatenate([f for f in mesh.facet_sets.values()]), axis=0)
    assert len(m.cells[1].data) == len(union)  # each face once, even if in two sets
    zmax = m.cell_data["facetset:zmax"]
    assert not zmax[0].any() and zmax[1].sum() == len(mesh.facet_set("zmax"))
    assert m.cell_data["facetset:contact"][1].sum() == 3
    assert m.point_data["nodeset:corner"].sum() == 1 and m.point_data["nodeset:corner"][0] == 1
    assert m.point_data["nodeset:all"].sum() == mesh.n_nodes


def test_vtu_from_another_program_with_only_hexes(tmp_path):
    mesh = box((1, 2, 3), (2, 2, 2))
    path = tmp_path / "plain.vtu"
    meshio.write(path, meshio.Mesh(mesh.points, [("hexahedron", mesh.cells)], point_data={"T": np.ones(27)}))
    back = read_mesh(path)
    assert np.array_equal(back.points, mesh.points) and np.array_equal(back.cells, mesh.cells)
    assert dict(back.node_sets) == {} and dict(back.facet_sets) == {}
    # a foreign file following the naming scheme: a node set and unmarked quads
    flag = np.zeros(27, np.int64)
    flag[:3] = 1
    quads = mesh.facet_nodes("zmin")
    meshio.write(
        path,
        meshio.Mesh(mesh.points, [("hexahedron", mesh.cells), ("quad", quads)], point_data={"nodeset:base": flag}),
    )
    back = read_mesh(path)
    assert dict(back.facet_sets) == {} and np.array_equal(back.node_sets["base"], [0, 1, 2])


@needs_netcdf4
def test_exodus_side_numbering_and_names(tmp_path):
    import netCDF4

    mesh = box((1, 1, 1), (2, 1, 1))
    path = tmp_path / "m.e"
    write_mesh(path, mesh, body_name="slab")
    expected_side = {"ymin": 1, "xmax": 2, "ymax": 3, "xmin": 4, "zmin": 5, "zmax": 6}  # Exodus II hex sides
    with netCDF4.Dataset(path) as nc:
        names = ["".join(c.decode() for c in row if c) for row in nc.variables["ss_names"][:]]
        assert sorted(names) == sorted(expected_side)
        for i, name in enumerate(names, start=1):
            assert set(nc.variables[f"side_ss{i}"][:].tolist()) == {expected_side[name]}
            elems = nc.variables[f"elem_ss{i}"][:] - 1
            assert np.array_equal(np.sort(elems), np.sort(mesh.facet_set(name)[:, 0]))
    assert sorted(read_bodies(path)) == ["slab"]


def test_exodus_without_netcdf4_says_what_is_missing(tmp_path, monkeypatch):
    import builtins

    real_import = builtins.__import__

    def fake_import(name, *args, **kwargs):
        if name == "netCDF4":
            raise ImportError("no netCDF4")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", fake_import)
    with pytest.raises(MeshError, match="netCDF4"):
        write_mesh(tmp_path / "m.exo", box())


# ------------------------------------------------------------ Gmsh's own files
def quad_vector_areas(mesh, name):
    p = mesh.points[mesh.facet_nodes(name)]
    return 0.5 * np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 1])


@pytest.mark.parametrize("text", [GMSH_41, GMSH_22], ids=["msh41", "msh22"])
def test_file_written_by_gmsh(tmp_path, text):
    path = tmp_path / "gmsh.msh"
    path.write_text(text)
    mesh = read_mesh(path)
    assert mesh.n_cells == 3 and mesh.n_nodes == 16
    assert sorted(mesh.facet_sets) == ["top", "xmin"]
    assert sorted(mesh.node_sets) == ["origin", "top", "xmin", "z_edge"]
    top = quad_vector_areas(mesh, "top")
    assert top.shape == (3, 3) and np.allclose(top.sum(axis=0), [0, 0, 2.0])
    assert np.all(top[:, 2] > 0)  # outward, whatever the orientation of Gmsh's quads
    assert np.allclose(quad_vector_areas(mesh, "xmin"), [[-1.0, 0, 0]])
    assert np.allclose(mesh.points[mesh.node_sets["origin"]], [[0, 0, 0]])
    assert sorted(map(tuple, mesh.points[mesh.node_sets["z_edge"]].tolist())) == [(0, 0, 0), (0, 0, 1)]
    assert np.allclose(mesh.points[mesh.node_sets["top"], 2], 1.0) and len(mesh.node_sets["top"]) == 8
    bodies = read_bodies(path)
    assert list(bodies) == ["block"]
    assert_same_mesh(bodies["block"], mesh)
    with pytest.raises(MeshError, match=r"no body 'nope'.*\['block'\]"):
        read_mesh(path, body="nope")


def two_body_file(path, conformal: bool, version="2.2"):
    """A slab and a die above it, as 3D physical groups, plus 2D groups on each."""
    slab = box((2.0, 1.0, 0.5), (2, 1, 1))
    die = box((1.0, 1.0, 0.5), (1, 1, 1), origin=(0.5 if not conformal else 0.0, 0.0, 0.5 if conformal else 0.6))
    if conformal:
        die = box((2.0, 1.0, 0.5), (2, 1, 1), origin=(0.0, 0.0, 0.5))
    offset = slab.n_nodes
    points = np.concatenate([slab.points, die.points])
    die_cells = die.cells + offset
    if conformal:  # share the interface nodes
        shared = {tuple(p): i for i, p in enumerate(slab.points.tolist())}
        remap = np.array([shared.get(tuple(p), offset + j) for j, p in enumerate(die.points.tolist())])
        die_cells = remap[die.cells]
    cells = [
        ("hexahedron", slab.cells),
        ("hexahedron", die_cells),
        ("quad", slab.facet_nodes("zmax")[:, ::-1]),  # reversed orientation on purpose
        ("quad", (die.facet_nodes("zmin") + offset) if not conformal else remap[die.facet_nodes("zmin")]),
        ("quad", slab.facet_nodes("zmin")),
    ]
    phys = [np.full(len(c[1]), t) for c, t in zip(cells, [1, 2, 3, 4, 5])]
    field = {"slab": [1, 3], "die": [2, 3], "slab_top": [3, 2], "die_bottom": [4, 2], "base": [5, 2]}
    meshio.write(
        path,
        meshio.Mesh(points, cells, cell_data={"gmsh:physical": phys, "gmsh:geometrical": phys}, field_data=field),
        file_format="gmsh22",
        binary=False,
    )
    return slab, die


def test_two_bodies_in_one_file(tmp_path):
    path = tmp_path / "two.msh"
    slab, die = two_body_file(path, conformal=False)
    whole = read_mesh(path)
    assert whole.n_cells == 3 and sorted(whole.facet_sets) == ["base", "die_bottom", "slab_top"]
    bodies = read_bodies(path)
    assert sorted(bodies) == ["die", "slab"]
    s, d = bodies["slab"], bodies["die"]
    assert np.array_equal(s.points, slab.points) and np.array_equal(s.cells, slab.cells)
    assert np.array_equal(d.points, die.points) and np.array_equal(d.cells, die.cells)
    assert sorted(s.facet_sets) == ["base", "slab_top"] and sorted(d.facet_sets) == ["die_bottom"]
    assert set(map(tuple, s.facet_sets["slab_top"].tolist())) == set(map(tuple, slab.facet_set("zmax").tolist()))
    assert np.array_equal(d.facet_sets["die_bottom"], die.facet_set("zmin"))
    assert_same_mesh(read_mesh(path, body="die"), d)


def test_bodies_sharing_nodes(tmp_path):
    path = tmp_path / "conformal.msh"
    two_body_file(path, conformal=True)
    # as one mesh the interface is interior: the group is named in the error
    msg = r"facet group 'slab_top': 2 of its 2 quads are not boundary faces.*read_bodies"
    with pytest.raises(MeshError, match=msg):
        read_mesh(path)
    bodies = read_bodies(path)
    assert bodies["slab"].n_cells == 2 and bodies["die"].n_cells == 2
    assert bodies["slab"].n_nodes == 12 and bodies["die"].n_nodes == 12  # renumbered per body
    # the interface quads have the same nodes in both bodies, so each body gets
    # both interface groups (on its own side of the interface)
    assert sorted(bodies["slab"].facet_sets) == ["base", "die_bottom", "slab_top"]
    assert sorted(bodies["die"].facet_sets) == ["die_bottom", "slab_top"]
    for name, body, sign in (("slab_top", "slab", 1), ("die_bottom", "die", -1)):
        assert np.allclose(quad_vector_areas(bodies[body], name).sum(axis=0), [0, 0, sign * 2.0])
    assert np.allclose(bodies["die"].points[bodies["die"].node_sets["die_bottom"], 2], 0.5)


# ---------------------------------------------------------------------- errors
def test_unsupported_suffix_and_missing_file(tmp_path):
    with pytest.raises(MeshError, match=r"unsupported mesh file type '.stl'.*\.msh"):
        read_mesh(tmp_path / "a.stl")
    with pytest.raises(MeshError, match=r"unsupported mesh file type"):
        write_mesh(tmp_path / "a.obj", box())
    with pytest.raises(MeshError, match=r"not found"):
        read_mesh(tmp_path / "missing.msh")
    with pytest.raises(MeshError, match=r"file_format='gmsh22' is not valid for '.vtu'"):
        write_mesh(tmp_path / "a.vtu", box(), file_format="gmsh22")


@pytest.mark.parametrize("suffix", [".msh", ".vtu"])
def test_wedges_are_refused(tmp_path, suffix):
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [0, 1, 1]], float)
    path = tmp_path / f"wedge{suffix}"
    kwargs = {"file_format": "gmsh22"} if suffix == ".msh" else {}
    tet = [("wedge", np.array([[0, 1, 2, 3, 4, 5]]))]
    if suffix == ".msh":
        tags = {"gmsh:physical": [[1]], "gmsh:geometrical": [[1]]}
        meshio.write(path, meshio.Mesh(pts, tet, cell_data=tags), **kwargs)
    else:
        meshio.write(path, meshio.Mesh(pts, tet))
    with pytest.raises(
        MeshError, match=r"only hexahedra \(hex8\) and tetrahedra \(tet4, tet10\) are supported.*1 wedge"
    ):
        read_mesh(path)


def test_file_without_hexahedra(tmp_path):
    pts = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    path = tmp_path / "quad.vtu"
    meshio.write(path, meshio.Mesh(pts, [("quad", np.array([[0, 1, 2, 3]]))]))
    with pytest.raises(MeshError, match=r"no hexahedra or tetrahedra found.*'quad': 1"):
        read_mesh(path)


def write_msh22(path, mesh, extra_cells, groups):
    """A .msh with the hexes of ``mesh`` plus extra cells in named 2D groups."""
    cells = [("hexahedron", mesh.cells), *extra_cells]
    tags = [np.full(len(c[1]), t) for c, t in zip(cells, [1, *[g[1] for g in groups]])]
    field = {"body": [1, 3], **{name: [tag, 2] for name, tag in groups}}
    meshio.write(
        path,
        meshio.Mesh(mesh.points, cells, cell_data={"gmsh:physical": tags, "gmsh:geometrical": tags}, field_data=field),
        file_format="gmsh22",
    )


def test_quad_that_is_not_a_boundary_face_names_its_group(tmp_path):
    mesh = box((2, 1, 1), (2, 1, 1))
    interior = mesh.cells[0][[1, 2, 6, 5]]  # the face shared by both cells
    path = tmp_path / "bad.msh"
    write_msh22(path, mesh, [("quad", np.array([interior, *mesh.facet_nodes("zmin")]))], [("press", 7)])
    with pytest.raises(MeshError, match=r"facet group 'press': 1 of its 3 quads are not boundary faces"):
        read_mesh(path)
    unrelated = np.array([[0, 1, 10, 11]])  # four nodes that are no face at all
    write_msh22(path, mesh, [("quad", unrelated)], [("weird", 7)])
    with pytest.raises(MeshError, match=r"'weird'"):
        read_mesh(path)


def test_triangles_in_a_facet_group_are_refused(tmp_path):
    mesh = box()
    path = tmp_path / "tri.msh"
    write_msh22(path, mesh, [("triangle", np.array([[0, 1, 2]]))], [("load", 3)])
    with pytest.raises(MeshError, match=r"physical group 'load' holds triangle elements"):
        read_mesh(path)


def test_msh_write_refuses_ambiguous_names(tmp_path):
    mesh = box((1, 1, 1), (2, 1, 1))
    clash = mesh.with_sets(node_sets={"xmin": [0]})
    with pytest.raises(MeshError, match=r"node set 'xmin' has the name of a facet set but other nodes"):
        write_mesh(tmp_path / "a.msh", clash)
    write_mesh(tmp_path / "a.vtu", clash)  # VTU keeps both
    assert np.array_equal(read_mesh(tmp_path / "a.vtu").node_sets["xmin"], [0])
    with pytest.raises(MeshError, match=r"body_name 'zmax' is also a set name"):
        write_mesh(tmp_path / "a.msh", mesh, body_name="zmax")
    with pytest.raises(MeshError, match=r"cannot be written"):
        write_mesh(tmp_path / "b.msh", mesh.with_sets(node_sets={'say "hi"': [0]}))


@pytest.mark.parametrize(
    "suffix, expected",
    [
        (".msh", "a Gmsh mesh file"),
        (".vtu", "a VTK XML unstructured grid"),
        pytest.param(".exo", "an Exodus II mesh file", marks=needs_netcdf4),
    ],
)
@pytest.mark.parametrize(
    "content, found",
    [
        (b"hello world\n", "it begins with 'hello world'"),
        (b"", "the file is empty"),
        (b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR\xff\xfe", "binary data"),
    ],
)
def test_a_file_that_is_no_mesh_is_one_line_naming_it_and_what_was_expected(
    tmp_path, suffix, expected, content, found, capsys
):
    """meshio.read prints a bare "Couldn't read file" and exits the process: never reached."""
    path = tmp_path / f"notes{suffix}"
    path.write_bytes(content)
    with pytest.raises(MeshError) as err:
        read_mesh(path)
    message = str(err.value)
    assert message.startswith(f"{path} is not {expected}") and found in message and "\n" not in message
    assert capsys.readouterr().out == ""


@pytest.mark.parametrize(
    "suffix, expected",
    [
        (".msh", "a Gmsh mesh file"),
        (".vtu", "a VTK XML unstructured grid"),
        pytest.param(".exo", "an Exodus II mesh file", marks=needs_netcdf4),
    ],
)
def test_a_mesh_file_cut_short_is_said_to_be_damaged_not_another_kind_of_file(tmp_path, suffix, expected):
    """It begins as the format does: the message must not say it does not (and then quote that beginning)."""
    whole = tmp_path / f"whole{suffix}"
    write_mesh(whole, box((1, 1, 1), (2, 2, 2)))
    path = tmp_path / f"cut{suffix}"
    path.write_bytes(whole.read_bytes()[: len(whole.read_bytes()) // 3])
    with pytest.raises(MeshError) as err:
        read_mesh(path)
    message = str(err.value)
    assert message.startswith(f"{path} begins as {expected} but cannot be read: it is cut short or damaged")
    assert message.endswith("; write it again") and "\n" not in message and "is not" not in message


def test_a_hex_with_a_repeated_node_is_blamed_on_itself_not_on_a_facet_set(tmp_path):
    """The file's facet quads are right; its hex 7 repeats a node of its xmax face."""
    mesh = box((1, 1, 1), (2, 2, 2))
    hexes = mesh.cells.copy()
    hexes[7, 6] = hexes[7, 5]
    quads = [mesh.facet_nodes(name) for name in ("xmax", "zmin")]
    for suffix in (".msh", ".vtu"):
        path = tmp_path / f"collapsed{suffix}"
        if suffix == ".msh":
            write_msh22(
                path, Mesh(mesh.points, hexes, check=False), [("quad", q) for q in quads], [("xmax", 7), ("zmin", 8)]
            )
        else:
            write_mesh(path, mesh)
            data = meshio.read(path)
            data.cells[0] = meshio.CellBlock("hexahedron", hexes)
            meshio.write(path, data)
        with pytest.raises(MeshError, match=r"hexahedron 7 \(0-based in file order\) is degenerate: repeated nodes"):
            read_mesh(path)


# ------------------------------------------------------------------ the size from the header, first
@pytest.mark.parametrize(
    "name, options",
    [
        ("msh41.msh", {}),
        ("msh41-ascii.msh", {"binary": False}),
        ("msh22.msh", {"file_format": "gmsh22"}),
        ("msh22-ascii.msh", {"file_format": "gmsh22", "binary": False}),
        ("grid.vtu", {}),
        pytest.param("grid.exo", {}, marks=needs_netcdf4),
    ],
)
def test_the_cells_a_file_declares_are_read_from_its_header(tmp_path, name, options):
    from contopt.mesh.headers import declared_cells
    from contopt.mesh.io import SUPPORTED_SUFFIXES

    mesh = box((1, 1, 1), (5, 4, 3))
    path = tmp_path / name
    write_mesh(path, mesh, **options)
    declared = declared_cells(path, SUPPORTED_SUFFIXES[path.suffix])
    if path.suffix == ".vtu":  # NumberOfCells counts the quads of the facet sets too: the 94 boundary faces
        assert declared == mesh.n_cells + 94
    else:
        assert declared == mesh.n_cells


@pytest.mark.parametrize(
    "name, text",
    [
        ("huge.msh", "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Elements\n1 2000000000 1 2000000000\n3 1 5 2000000000\n"),
        (  # binary MSH 2.2: one block header of 2e9 hexahedra with 2 tags
            "huge22.msh",
            b"$MeshFormat\n2.2 1 8\n\x01\x00\x00\x00\n$EndMeshFormat\n$Elements\n2000000000\n"
            + struct.pack("<iii", 5, 2_000_000_000, 2),
        ),
        (
            "huge.vtu",
            '<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid"><UnstructuredGrid>'
            '<Piece NumberOfPoints="8" NumberOfCells="2000000000">',
        ),
    ],
)
def test_a_file_whose_header_declares_too_many_cells_is_refused_before_it_is_read(tmp_path, name, text):
    """2e9 hexahedra need at least 30 TiB: refused from the header (a 2-million-cell file was read for
    50-155 s and 4.1 GB before the check)."""
    path = tmp_path / name
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    with pytest.raises(MeshError) as err:
        read_mesh(path)
    message = str(err.value)
    assert message.startswith(f"the mesh file {path} (by its header) would have 2e+09 cells; an analysis of it")
    assert message.endswith("use a coarser mesh") or message.endswith("use a coarser mesh, or raise the limit")
