"""Headless pictures: exact size, not blank, and they show the field they are given."""

import matplotlib.image as mpimg
import numpy as np
import pytest

from contopt.errors import ConfigError
from contopt.io import render
from contopt.io.plots import plot_pressure_history, pressure_history_figure
from contopt.io.render import BodyGrid, last_vtus, render_deformed, render_design
from contopt.io.vtk import PVDSeries, write_vtu
from contopt.mesh.generators import box

SIZE = (320, 240)
PNG = b"\x89PNG\r\n\x1a\n"


def _png(path, size=SIZE) -> np.ndarray:
    """The RGB pixels (h, w, 3) in [0, 1] of a PNG of exactly ``size`` = (w, h)."""
    assert path.read_bytes()[:8] == PNG
    img = mpimg.imread(path)
    assert img.shape[:2] == (size[1], size[0])
    return img[..., :3]


def _red(img) -> int:
    """Reddish pixels (the nu >= 0.9 surface, also seen through the green one), outside the axes triad
    (the lower-left fifth of the picture, whose x axis is red too)."""
    img = img.copy()
    h, w = img.shape[:2]
    img[int(0.8 * h) :, : int(0.2 * w)] = 1.0
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    return int(np.sum(r - np.maximum(g, b) > 0.3))


@pytest.fixture(scope="module")
def cube():
    return box((1.0, 1.0, 1.0), (8, 8, 8))


def _ball(mesh, radius=0.3):
    centres = mesh.points[mesh.cells].mean(axis=1)
    return (np.linalg.norm(centres - 0.5, axis=1) < radius).astype(float)


def test_design_picture_shows_the_iso_surfaces_of_nu(tmp_path, cube):
    ball = render_design(
        [BodyGrid("block", cube.points, cube.cells, {"nu": _ball(cube)})], tmp_path / "ball.png", size=SIZE
    )
    flat = render_design(
        [BodyGrid("block", cube.points, cube.cells, {"nu": np.full(len(cube.cells), 0.5)})],
        tmp_path / "flat.png",
        size=SIZE,
    )
    a, b = _png(ball), _png(flat)
    assert a.std() > 0.02 and b.std() > 0.02  # not blank: the white background is not all there is
    assert np.abs(a - b).mean() > 0.01
    # the ball is solid (nu = 1 >= 0.9): red; the uniform 0.5 has no region nu >= 0.9
    assert _red(a) > 200 and _red(b) == 0
    assert not list(tmp_path.glob(".*"))  # written atomically: no temporaries left


def test_design_picture_draws_undesigned_bodies_as_context(tmp_path, cube):
    punch = box((0.4, 0.4, 0.2), (2, 2, 1), origin=(0.3, 0.3, 1.0))
    designed = BodyGrid("block", cube.points, cube.cells, {"nu": _ball(cube)})
    other = BodyGrid("punch", punch.points, punch.cells)
    with_ctx = _png(render_design([designed, other], tmp_path / "a.png", size=SIZE))
    without = _png(render_design([designed, other], tmp_path / "b.png", size=SIZE, context=False))
    assert np.abs(with_ctx - without).mean() > 1e-3


def test_deformed_picture_is_coloured_by_contact_pressure(tmp_path, cube):
    p = np.where(cube.points[:, 2] > 0.99, 1.0 - np.abs(cube.points[:, 0] - 0.5), 0.0)  # top face only
    u = np.zeros_like(cube.points)
    u[:, 0] = 0.3 * cube.points[:, 2]  # a visible shear
    nu = np.ones(len(cube.cells))
    still = BodyGrid("block", cube.points, cube.cells, {"nu": nu}, {"contact_pressure": p})
    sheared = BodyGrid("block", cube.points, cube.cells, {"nu": nu}, {"contact_pressure": p, "displacement": u})
    a = _png(render_deformed([still], tmp_path / "still.png", size=SIZE))
    b = _png(render_deformed([sheared], tmp_path / "sheared.png", size=SIZE))
    assert a.std() > 0.02 and np.abs(a - b).mean() > 0.01
    # nu >= 0.5 hides the void cells: an all-void design shows less of the body than an all-solid one
    void = BodyGrid("block", cube.points, cube.cells, {"nu": np.zeros(len(cube.cells))}, {"contact_pressure": p})
    c = _png(render_deformed([void], tmp_path / "void.png", size=SIZE))
    assert (c.sum(axis=2) < 2.9).sum() < (a.sum(axis=2) < 2.9).sum()  # fewer non-white pixels


def test_last_vtus_from_the_pvd_or_the_files(tmp_path, cube):
    series = PVDSeries(tmp_path / "design.pvd")
    for index in range(3):
        for part, name in enumerate(("block", "punch")):
            f = write_vtu(
                tmp_path / "vtu" / f"{name}_{index:04d}.vtu",
                cube.points,
                cube.cells,
                cell_data={"nu": np.full(len(cube.cells), index / 2)},
            )
            series.add(float(index), f, part)
    expected = [tmp_path / "vtu" / "block_0002.vtu", tmp_path / "vtu" / "punch_0002.vtu"]
    assert [p.resolve() for p in last_vtus(tmp_path)] == [p.resolve() for p in expected]
    (tmp_path / "design.pvd").unlink()
    assert sorted(p.resolve() for p in last_vtus(tmp_path)) == sorted(p.resolve() for p in expected)
    assert last_vtus(tmp_path / "elsewhere") == []
    # a VTU written by meshio renders (nu is stored (m, 1))
    img = _png(render_design(expected[:1], tmp_path / "from_vtu.png", size=SIZE))
    assert _red(img) > 200  # nu = 1 everywhere in the last file


def test_picture_size_is_validated(tmp_path, cube):
    body = BodyGrid("block", cube.points, cube.cells, {"nu": _ball(cube)})
    for bad in ((0, 10), (10,), (12.5, 10), "big"):
        with pytest.raises(ConfigError, match="size must be two positive integers"):
            render_design([body], tmp_path / "x.png", size=bad)
    assert not (tmp_path / "x.png").exists()


def test_no_opengl_is_a_clear_error(tmp_path, cube, monkeypatch):
    monkeypatch.delenv("VTK_DEFAULT_OPENGL_WINDOW", raising=False)
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.setattr(render, "_probe", lambda window: "it drew a blank image")
    monkeypatch.setattr(render, "_osmesa_available", lambda: True)
    render._choose_window.cache_clear()
    try:
        with pytest.raises(
            render.RenderError, match="vtkEGLRenderWindow: it drew a blank image; vtkOSOpenGLRenderWindow: .*libegl1"
        ):
            render_design([BodyGrid("block", cube.points, cube.cells, {"nu": _ball(cube)})], tmp_path / "x.png")
    finally:
        render._choose_window.cache_clear()  # the next picture probes the real machine again
    assert not (tmp_path / "x.png").exists()


def test_pressure_history_has_one_line_per_node(tmp_path):
    it = np.arange(5)
    lam = np.outer(np.linspace(0.0, 1.0, 5), np.arange(7.0))  # (5 iterations, 7 nodes)
    f = np.linspace(-0.2, -0.6, 5)
    fig = pressure_history_figure(it, lam, f)
    try:
        lines = fig.axes[0].get_lines()
        assert len(lines) == 7
        for j, line in enumerate(lines):
            np.testing.assert_array_equal(line.get_ydata(), lam[:, j])
        np.testing.assert_array_equal(fig.axes[1].get_lines()[0].get_ydata(), f)
    finally:
        import matplotlib.pyplot as plt

        plt.close(fig)
    path = plot_pressure_history(it, lam, f, tmp_path / "p.png")
    assert path.read_bytes()[:8] == PNG and path.stat().st_size > 10_000
    with pytest.raises(ValueError, match=r"pressures must be \(k, n_nodes\)"):
        pressure_history_figure(it, lam[:4], f)


def test_surface_picture_shows_the_surface_given_or_read_from_a_file(tmp_path):
    from contopt.io.render import render_surface
    from contopt.io.surface import lattice_surface, write_surface

    g = np.linspace(-1.2, 1.2, 25)
    X = np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1)
    ball = lattice_surface(1.0 - np.linalg.norm(X, axis=-1), (g[0],) * 3, (g[1] - g[0],) * 3)
    stl = write_surface(ball, tmp_path / "ball.stl")
    shown = _png(render_surface([ball], tmp_path / "a.png", size=SIZE))
    read = _png(render_surface([stl], tmp_path / "b.png", size=SIZE))
    empty = _png(render_surface([], tmp_path / "c.png", size=SIZE, boxes=[((-1, -1, -1), (1, 1, 1))]))
    covered = lambda img: float(np.mean(img.min(axis=-1) < 0.9))  # noqa: E731  not white
    assert covered(shown) > 0.1 and covered(empty) < 0.05
    assert np.abs(shown - read).mean() < 0.01  # the file holds the same surface (float32)


def _red_above_the_bar(img) -> int:
    """Dark red pixels (nu near 1 in the 'Reds' colormap) in the upper 70 % of a sections picture
    (its scalar bar sits below)."""
    top = img[: int(0.7 * img.shape[0])]
    r, g, b = top[..., 0], top[..., 1], top[..., 2]
    return int(np.sum((r > 0.3) & (r - np.maximum(g, b) > 0.25)))


def test_sections_cut_through_the_designed_body_where_asked(tmp_path, cube):
    from contopt.io.render import render_sections

    grid = BodyGrid("block", cube.points, cube.cells, {"nu": _ball(cube)})
    size = (600, 240)
    # the ball (radius 0.3 about the centre) is cut at mid-height, missed at a tenth of it
    through = _png(render_sections([grid], tmp_path / "mid.png", axis="z", positions=(0.5,), size=size), size)
    beside = _png(render_sections([grid], tmp_path / "low.png", axis="z", positions=(0.1,), size=size), size)
    assert _red_above_the_bar(through) > 200
    assert _red_above_the_bar(beside) == 0
    assert not list(tmp_path.glob(".*"))


def test_sections_refuse_bad_positions_and_undesigned_bodies(tmp_path, cube):
    from contopt.io.render import render_sections

    grid = BodyGrid("block", cube.points, cube.cells, {"nu": _ball(cube)})
    for bad in ((), (0.0,), (0.5, 1.2)):
        with pytest.raises(ConfigError, match="fractions strictly between 0 and 1"):
            render_sections([grid], tmp_path / "x.png", positions=bad)
    with pytest.raises(ConfigError, match="no designed body"):
        render_sections([BodyGrid("block", cube.points, cube.cells)], tmp_path / "x.png")
    with pytest.raises(ConfigError, match="up axis"):
        render_sections([grid], tmp_path / "x.png", axis="w")
