"""The robust formulation's length scale: the promised minimum and the measure on a design."""

import numpy as np
import pytest

from contopt.design.length_scale import local_thickness, member_sizes, robust_length_scale
from contopt.errors import ConfigError


@pytest.mark.parametrize("delta", [0.05, 0.15, 0.25, 0.35])
def test_the_closed_form_is_the_wall_under_the_1d_hat_filter(delta):
    """2 R sqrt(delta) (delta <= 1/4), 2 R (1 - sqrt(1/2 - delta)) above: the quadrature of the wall
    argument with the 1D kernel, done here independently of the module."""
    s = np.linspace(-3.0, 3.0, 600001)
    hat = np.maximum(1.0 - np.abs(s), 0.0)
    cdf = np.cumsum(hat) * (s[1] - s[0])
    half = np.linspace(0.0, 1.0, 100001)
    middle = np.interp(half, s, cdf) - np.interp(-half, s, cdf)  # the filtered density in the middle of |x| < half
    a = np.interp(0.5 + delta, middle, half)  # the wall whose middle just reaches the eroded threshold
    filtered = np.interp(s + a, s, cdf) - np.interp(s - a, s, cdf)
    width = 2 * s[(s >= 0) & (filtered >= 0.5)].max()
    assert robust_length_scale(2.0, delta) == pytest.approx(2.0 * width, abs=1e-4)
    # the cone filter of 2D and 3D meshes averages over a disc or ball: a little less
    assert robust_length_scale(2.0, delta, 3) < robust_length_scale(2.0, delta, 2) < robust_length_scale(2.0, delta)
    with pytest.raises(ConfigError, match="delta in"):
        robust_length_scale(1.0, 0.5)


def test_local_thickness_of_a_bar_and_a_disc():
    bar = np.zeros((40, 30), bool)
    bar[10:18, 2:28] = True  # 8 wide
    t = local_thickness(bar, 0.5)
    assert 3.5 <= t[bar].max() <= 4.0 and np.median(t[bar]) >= 3.5  # 8 points of spacing 0.5
    y, x = np.mgrid[:41, :41]
    disc = (x - 20) ** 2 + (y - 20) ** 2 <= 15**2
    assert local_thickness(disc, 1.0)[20, 20] == pytest.approx(30.0, abs=1.0)


def test_member_sizes_of_known_shapes():
    """A bar 6 cells wide and a slot 4 cells wide, on cells of size 0.5, measured within the lattice
    spacing h / refine; a plate one cell thick is measured in its plane."""
    g = np.zeros((40, 40))
    g[5:11, 5:35] = 1.0
    g[15:35, 5:35] = 1.0
    g[15:35, 18:22] = 0.0
    member, gap = member_sizes(g, 0.5, refine=4)
    assert member == pytest.approx(3.0, abs=0.5 / 4 + 1e-9) and gap == pytest.approx(2.0, abs=0.5 / 4 + 1e-9)
    assert member_sizes(g[:, :, None], 0.5) == (member, gap)
    assert member_sizes(np.ones((4, 4)), 1.0)[1] == float("inf")
