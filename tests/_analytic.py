"""Hand-derived reference solutions shared by the material and element tests.

Independent of the code under test: the compressible Mooney-Rivlin law of
the paper's appendix C differentiated by hand.
"""

import numpy as np
from scipy.optimize import brentq


def rel_err(a, b):
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


def principal_cauchy(mat, l):
    """Principal Cauchy stresses sigma_i = (l_i / J) dW/dl_i for F = diag(l), differentiated by hand.

    W = kappa/2 (ln J)^2 + A (J^(-2/3) I1 - 3) + B (J^(-4/3) I2 - 3) with
    I1 = sum l_i^2, I2 = sum_{i<j} l_i^2 l_j^2, J = l1 l2 l3, so
    dI1/dl_i = 2 l_i, dI2/dl_i = 2 l_i (I1 - l_i^2), dJ/dl_i = J / l_i and

    dW/dl_i = kappa lnJ / l_i
              + A J^(-2/3) (2 l_i - 2/3 I1 / l_i)
              + B J^(-4/3) (2 l_i (I1 - l_i^2) - 4/3 I2 / l_i).
    """
    kappa, A, B = mat.kappa, mat.A, mat.B
    l = np.asarray(l, float)
    J = l[0] * l[1] * l[2]
    I1 = np.sum(l**2)
    I2 = l[0] ** 2 * l[1] ** 2 + l[0] ** 2 * l[2] ** 2 + l[1] ** 2 * l[2] ** 2
    dW = (
        kappa * np.log(J) / l
        + A * J ** (-2.0 / 3.0) * (2.0 * l - 2.0 / 3.0 * I1 / l)
        + B * J ** (-4.0 / 3.0) * (2.0 * l * (I1 - l**2) - 4.0 / 3.0 * I2 / l)
    )
    return l / J * dW


def uniaxial_lateral_stretch(mat, l1):
    """l2 = l3 such that sigma_2 = sigma_3 = 0 for F = diag(l1, l2, l2) (hand formula + brentq)."""
    return brentq(lambda l2: principal_cauchy(mat, [l1, l2, l2])[1], 0.2, 3.0, xtol=1e-15, rtol=1e-15)


def cauchy_hand(mat, F):
    """sigma = 2/J dev(A J^-2/3 b + B J^-4/3 (I1 b - b^2)) + kappa lnJ / J I (general F)."""
    F = np.asarray(F, float)
    J = np.linalg.det(F)
    b = F @ F.T
    I1 = np.trace(b)
    s = mat.A * J ** (-2.0 / 3.0) * b + mat.B * J ** (-4.0 / 3.0) * (I1 * b - b @ b)
    dev = s - np.trace(s) / 3.0 * np.eye(3)
    return 2.0 / J * dev + mat.kappa * np.log(J) / J * np.eye(3)
