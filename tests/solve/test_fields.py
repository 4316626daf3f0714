import numpy as np

from contopt.solve.fields import von_mises


def test_von_mises_of_simple_states():
    uni = np.diag([3.0, 0.0, 0.0])
    shear = np.array([[0, 2.0, 0], [2.0, 0, 0], [0, 0, 0]])
    hydro = 5.0 * np.eye(3)
    np.testing.assert_allclose(von_mises(np.stack([uni, shear, hydro])), [3.0, 2.0 * np.sqrt(3.0), 0.0], atol=1e-14)
