"""CAD in (contopt.mesh.cad): hex8 meshes of CAD solids written by Gmsh's OpenCASCADE kernel here.

The references are the solids' own: a cylinder's volume and face areas (the mesh is inscribed, so it
falls short by at most the sagitta of its longest chord over the curved faces), a box's exact ones,
and the uniaxial stress of a compressed block (a linear field, which trilinear hexes reproduce
whatever their shape: the tetrahedra split into skewed hexes pass the patch test).
"""

import math

import numpy as np
import pytest
from _analytic import principal_cauchy, uniaxial_lateral_stretch  # tests/_analytic.py (hand formulas)

from contopt.errors import ConfigError, MeshError
from contopt.mesh import read_mesh, scaled_jacobian, write_mesh
from contopt.mesh.cad import CadOptions, cad_surfaces, mesh_cad, surface_set_name
from contopt.mesh.tool import QuadSurface

gmsh = pytest.importorskip("gmsh")

_REF = np.array(
    [[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1], [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]],
    dtype=float,
)


def hex_volumes(mesh):
    """(m,) exact volumes of trilinear hexes (2x2x2 Gauss is exact for det J)."""
    x = mesh.points[mesh.cells]
    vol = np.zeros(mesh.n_cells)
    g = 1 / np.sqrt(3)
    for xi in np.array(np.meshgrid([-g, g], [-g, g], [-g, g])).reshape(3, -1).T:
        f = 1 + _REF * xi
        dN = _REF * np.stack([f[:, 1] * f[:, 2], f[:, 0] * f[:, 2], f[:, 0] * f[:, 1]], axis=1) / 8
        vol += np.linalg.det(np.einsum("mni,nj->mij", x, dN))
    return vol


def write_cad(path, make):
    """Write the solid ``make(occ)`` builds with Gmsh's OpenCASCADE kernel to ``path`` (suffix: format)."""
    gmsh.initialize(readConfigFiles=False, interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        make(gmsh.model.occ)
        gmsh.model.occ.synchronize()
        if str(path).endswith(".stl"):
            gmsh.option.setNumber("Mesh.MeshSizeMax", 0.5)
            gmsh.model.mesh.generate(2)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()
    return path


R, H = 1.0, 2.0


@pytest.fixture(scope="module")
def cylinder_step(tmp_path_factory):
    return write_cad(tmp_path_factory.mktemp("cad") / "cylinder.step", lambda occ: occ.addCylinder(0, 0, 0, 0, 0, H, R))


def facet_area(mesh, name):
    return float(QuadSurface(mesh.points, mesh.facet_nodes(mesh.facet_set(name))).areas().sum())


def longest_edge(mesh):
    x = mesh.points[mesh.cells]
    edges = [(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4), (0, 4), (1, 5), (2, 6), (3, 7)]
    return max(float(np.linalg.norm(x[:, a] - x[:, b], axis=1).max()) for a, b in edges)


def test_a_step_cylinder_meshes_into_valid_hexes_of_its_volume_and_faces(cylinder_step):
    size = 0.25
    mesh = mesh_cad(cylinder_step, size)
    assert scaled_jacobian(mesh).min() > 0  # every hex valid at every corner
    # the mesh is inscribed: flat faces exact, each chord of length <= L on a circle of radius R
    # cuts off at most its sagitta L^2 / (8 R) across the curved face
    L = longest_edge(mesh)
    sagitta = L**2 / (8 * R)
    lateral, end = 2 * math.pi * R * H, math.pi * R**2
    volume = hex_volumes(mesh).sum()
    assert 0 < math.pi * R**2 * H - volume <= lateral * sagitta
    # the faces: surface_N by Gmsh's tags (OCC's cylinder: 1 the mantle, 2 and 3 the ends)
    listed = {s.name: s.area for s in cad_surfaces(cylinder_step)}
    assert sorted(mesh.facet_sets) == sorted(listed) == ["surface_1", "surface_2", "surface_3"]
    assert listed["surface_1"] == pytest.approx(lateral, rel=1e-9)
    areas = {name: facet_area(mesh, name) for name in mesh.facet_sets}
    assert sum(len(mesh.facet_set(n)) for n in mesh.facet_sets) == len(mesh.boundary_facets())
    assert 0 < lateral - areas["surface_1"] <= lateral * L**2 / (8 * R**2)  # chords shorter than arcs
    for end_face in ("surface_2", "surface_3"):
        assert listed[end_face] == pytest.approx(end, rel=1e-9)
        assert 0 < end - areas[end_face] <= 2 * math.pi * R * sagitta  # the inscribed polygon
        z = mesh.points[mesh.node_set(end_face), 2]
        assert np.ptp(z) == 0 and z[0] in (0.0, H)
    # the edges are about size long: Gmsh's tetrahedra of edge 2 size, halved by the split
    assert size < L < 3 * size


def test_finer_size_converges_to_the_cylinder_volume(cylinder_step):
    exact = math.pi * R**2 * H
    errors = [exact - hex_volumes(mesh_cad(cylinder_step, size)).sum() for size in (0.4, 0.2)]
    assert errors[1] < errors[0] / 2.5  # second order: the sagitta goes as size^2


def test_scale_mm_to_m_scales_volume_by_1e_9(cylinder_step):
    mm = mesh_cad(cylinder_step, 0.4)
    m = mesh_cad(cylinder_step, 0.4e-3, scale=1e-3)
    assert np.ptp(m.points, axis=0) == pytest.approx(1e-3 * np.ptp(mm.points, axis=0), rel=1e-12)
    assert hex_volumes(m).sum() == pytest.approx(1e-9 * hex_volumes(mm).sum(), rel=1e-6)
    assert cad_surfaces(cylinder_step, scale=1e-3)[0].area == pytest.approx(1e-6 * 2 * math.pi * R * H, rel=1e-9)


@pytest.mark.parametrize("suffix", [".brep", ".iges", ".stl"])
def test_a_box_from_brep_iges_or_stl_has_its_exact_volume_and_six_faces(tmp_path, suffix):
    path = write_cad(tmp_path / f"box{suffix}", lambda occ: occ.addBox(0, 0, 0, 1, 2, 3))
    mesh = mesh_cad(path, 0.4)
    assert scaled_jacobian(mesh).min() > 0
    assert hex_volumes(mesh).sum() == pytest.approx(6.0, rel=1e-12)
    assert len(mesh.facet_sets) == 6
    areas = sorted(facet_area(mesh, name) for name in mesh.facet_sets)
    np.testing.assert_allclose(areas, [2, 2, 3, 3, 6, 6], rtol=1e-12)


def test_the_mesh_round_trips_through_msh_with_its_surface_sets(cylinder_step, tmp_path):
    mesh = mesh_cad(cylinder_step, 0.4)
    write_mesh(tmp_path / "c.msh", mesh)
    back = read_mesh(tmp_path / "c.msh")
    np.testing.assert_array_equal(back.cells, mesh.cells)
    for name in mesh.facet_sets:
        np.testing.assert_array_equal(back.facet_set(name), mesh.facet_set(name))


def test_surface_set_names_are_the_last_label_part_else_surface_n():
    assert surface_set_name(7, "Shapes/jaw/grip face") == "grip face"
    assert surface_set_name(7, "top") == "top"
    assert surface_set_name(7, "") == "surface_7"
    assert surface_set_name(3, "Shapes/") == "surface_3"


def test_options_and_files_are_checked_in_one_line(cylinder_step, tmp_path):
    with pytest.raises(ConfigError, match='mesh.order = 2 is tet10: set element = "tet"'):
        CadOptions(size=0.2, order=2)
    for bad in (
        {"size": 0.0},
        {"size": 0.2, "scale": -1.0},
        {"size": 0.2, "order": 3},
        {"size": 0.2, "element": "hex"},
    ):
        with pytest.raises(ConfigError, match="mesh\\.(size|scale|order|element) must be"):
            CadOptions(**bad)
    with pytest.raises(MeshError, match="not a CAD file"):
        mesh_cad(tmp_path / "part.obj", 0.2)
    with pytest.raises(MeshError, match="not found"):
        mesh_cad(tmp_path / "part.step", 0.2)
    two = write_cad(tmp_path / "two.step", lambda occ: (occ.addBox(0, 0, 0, 1, 1, 1), occ.addBox(2, 0, 0, 1, 1, 1)))
    with pytest.raises(MeshError, match="holds 2 solids; a body is meshed from one solid"):
        mesh_cad(two, 0.5)
    with pytest.raises(MeshError, match="would have .* cells.*use a larger size"):
        mesh_cad(cylinder_step, 1e-5)


def test_a_compressed_cad_block_has_the_uniaxial_stress_answer(tmp_path):
    """The block (1 x 1 x 2) compressed 1 % along z on rollers: the homogeneous uniaxial stress, to the
    Newton tolerance (a linear field), and E * strain * area to O(strain) (small strain)."""
    from contopt.assembly.model import Body, Dirichlet, Model
    from contopt.assembly.system import discretize
    from contopt.material.hyperelastic import neo_hookean
    from contopt.solve.newton import NewtonOptions
    from contopt.solve.static import solve_static

    L = (1.0, 1.0, 2.0)
    mesh = mesh_cad(write_cad(tmp_path / "block.step", lambda occ: occ.addBox(0, 0, 0, *L)), 0.4)
    plane = {}  # the facet set on each face of the box, found by its nodes' coordinates
    for name in mesh.facet_sets:
        x = mesh.points[mesh.node_set(name)]
        axis = int(np.argmin(np.ptp(x, axis=0)))
        plane[("xyz"[axis], "min" if x[0, axis] == 0 else "max")] = name
    E, nu, l3 = 1.0, 0.3, 0.99
    mat = neo_hookean(E, nu)
    bcs = [Dirichlet("b", plane[(a, "min")], a, 0.0) for a in "xyz"]
    bcs.append(Dirichlet("b", plane[("z", "max")], "z", (l3 - 1.0) * L[2]))
    newton = NewtonOptions(rtol=1e-12, atol=1e-15, utol=1e-12, n_steps=1, max_iter=30)
    disc = discretize(Model(bodies=[Body("b", mesh, mat)], dirichlet=bcs))
    state = solve_static(disc, newton=newton)
    u = disc.body_displacement(state.u, "b")
    l1 = uniaxial_lateral_stretch(mat, l3)
    tol = 1e-8  # the residual's 1e-12, times the conditioning of a few hundred skewed hexes
    np.testing.assert_allclose(u, mesh.points * (np.array([l1, l1, l3]) - 1.0), rtol=0, atol=tol * L[2])
    s33 = principal_cauchy(mat, [l3, l1, l1])[0]
    fz = state.reactions.reshape(-1, 3)[mesh.node_set(plane[("z", "max")]), 2].sum()
    assert fz == pytest.approx(s33 * l1**2 * L[0] * L[1], rel=tol)
    strain = l3 - 1.0
    assert fz == pytest.approx(E * strain * L[0] * L[1], rel=3 * abs(strain))  # small strain: Hooke
