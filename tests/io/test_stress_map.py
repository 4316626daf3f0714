"""The stress map: exact size, and it shows the stress of the solid cells it is given."""

import matplotlib.image as mpimg
import numpy as np

from contopt.io.render import BodyGrid
from contopt.io.stress_map import has_stress, render_stress
from contopt.mesh.generators import box

SIZE = (320, 240)


def _img(path):
    img = mpimg.imread(path)
    assert img.shape[:2] == (SIZE[1], SIZE[0])
    return img[..., :3]


def _dark(img) -> int:
    """Pixels near the dark end of the colour map (a low stress), outside the colour bar and the axes triad."""
    img = img[:, : int(0.75 * img.shape[1])].copy()
    img[int(0.8 * img.shape[0]) :, : int(0.2 * img.shape[1])] = 1.0
    return int(np.sum(img.max(axis=-1) < 0.3))


def test_the_map_is_coloured_by_the_stress_on_a_scale_up_to_its_peak(tmp_path):
    mesh = box((1.0, 1.0, 1.0), (6, 6, 6))
    centres = mesh.points[mesh.cells].mean(axis=1)
    nu = np.where(centres[:, 2] < 0.7, 1.0, 0.0)  # the top layers void
    peak = np.where(np.linalg.norm(centres[:, :2] - 0.5, axis=1) < 0.25, 1.0, 0.1)  # a hot core
    grid = BodyGrid("slab", mesh.points, mesh.cells, {"nu": nu, "von_mises": peak})
    uniform = BodyGrid("slab", mesh.points, mesh.cells, {"nu": nu, "von_mises": np.full(len(nu), 0.1)})
    assert has_stress([grid]) and not has_stress([BodyGrid("slab", mesh.points, mesh.cells, {"nu": nu})])
    hot = _img(render_stress([grid], tmp_path / "hot.png", size=SIZE))
    flat = _img(render_stress([uniform], tmp_path / "flat.png", size=SIZE))
    assert hot.std() > 0.02
    # on the scale 0 to the peak, the cells around the hot core (a tenth of it) are dark; a uniform
    # stress is all the top of the scale, bright
    assert _dark(hot) > 500 and _dark(flat) < 50
