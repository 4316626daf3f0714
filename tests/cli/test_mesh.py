"""`contopt mesh`: a CAD file meshed once and written, its surfaces listed; a mesh file's sets listed."""

import re

import pytest

from contopt.cli import main
from contopt.mesh import read_mesh

gmsh = pytest.importorskip("gmsh")


@pytest.fixture
def cylinder_step(tmp_path):
    gmsh.initialize(readConfigFiles=False, interruptible=False)
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.occ.addCylinder(0, 0, 0, 0, 0, 2, 1)
    gmsh.model.occ.synchronize()
    gmsh.write(str(tmp_path / "part.step"))
    gmsh.finalize()
    return tmp_path / "part.step"


def test_mesh_writes_the_hex_mesh_with_its_surface_sets_and_lists_them(cylinder_step, tmp_path, capsys):
    capsys.readouterr()
    out = tmp_path / "part.msh"
    assert main(["mesh", str(cylinder_step), "--size", "0.4", "--out", str(out), "--list"]) == 0
    said = capsys.readouterr().out
    mesh = read_mesh(out)
    assert f"{mesh.n_cells} hex8 cells" in said and f"wrote {out}" in said
    for name in ("surface_1", "surface_2", "surface_3"):
        faces = re.search(rf"{name} +(\d+) faces, area ([0-9.]+)", said)
        assert faces and int(faces.group(1)) == len(mesh.facet_set(name))
    assert main(["mesh", str(out), "--list"]) == 0  # the file written lists the same sets
    assert "surface_1" in capsys.readouterr().out


def test_mesh_writes_a_tet10_mesh_with_element_tet(cylinder_step, tmp_path, capsys):
    capsys.readouterr()
    out = tmp_path / "part.msh"
    assert (
        main(
            [
                "mesh",
                str(cylinder_step),
                "--size",
                "0.4",
                "--element",
                "tet",
                "--order",
                "2",
                "--out",
                str(out),
                "--list",
            ]
        )
        == 0
    )
    said = capsys.readouterr().out
    mesh = read_mesh(out)
    assert mesh.element == "tet10" and f"{mesh.n_cells} tet10 cells" in said
    area = re.search(r"surface_2 +(\d+) faces, area ([0-9.]+)", said)  # an end: the unit disc, the polygon's area
    assert area and float(area.group(2)) == pytest.approx(3.141592653589793, rel=0.02)


def test_list_without_size_lists_the_cad_surfaces_without_meshing(cylinder_step, capsys):
    capsys.readouterr()
    assert main(["mesh", str(cylinder_step), "--list", "--scale", "0.001"]) == 0
    said = capsys.readouterr().out
    area = re.search(r"surface_1 +Gmsh tag 1 +area ([0-9.e-]+)", said)
    assert area and float(area.group(1)) == pytest.approx(4e-6 * 3.141592653589793, rel=1e-5)


@pytest.mark.parametrize(
    "args, said",
    [
        ([], "needs --size"),
        (["--size", "0.2", "--order", "2"], 'mesh.order = 2 is tet10: set element = "tet"'),
        (["--size", "0"], "mesh.size must be a number > 0"),
    ],
)
def test_a_bad_call_is_one_line(cylinder_step, capsys, args, said):
    assert main(["mesh", str(cylinder_step), *args]) == 2
    err = capsys.readouterr().err.strip()
    assert said in err and "\n" not in err


def test_envelope_writes_the_voxels_of_a_closed_surface(tmp_path, capsys):
    from _envelope import write_bracket  # tests/_envelope.py

    from contopt.mesh.voxel import mesh_envelope

    stl = write_bracket(tmp_path / "bracket.stl")
    out = tmp_path / "bracket.vtu"
    capsys.readouterr()
    assert main(["mesh", str(stl), "--envelope", "--size", "0.1", "--out", str(out), "--list"]) == 0
    said = capsys.readouterr().out
    mesh = read_mesh(out)
    n = mesh_envelope(stl, 0.1).n_cells
    assert mesh.n_cells == n and f"{n} hex8 cells of edge 0.1" in said and f"wrote {out}" in said
    assert set(mesh.facet_sets) >= {"boundary", "xmin", "zmax"}
    assert main(["mesh", str(stl), "--envelope"]) == 2
    assert "needs --size" in capsys.readouterr().err
