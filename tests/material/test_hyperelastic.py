"""Mooney-Rivlin / neo-Hookean energies (paper appendix C) against independent references.

References used here, none of them produced by the code under test:
central finite differences of psi and of P, Cauchy stresses derived by hand
from the principal-stretch form of W, the simple-shear closed form, the
isotropic small-strain tensor of paper eq. (C.7), and the engineering
relations between (E, nu) and (kappa, mu).
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from _analytic import (
    cauchy_hand,
    principal_cauchy,
    rel_err,
    uniaxial_lateral_stretch,
)  # tests/_analytic.py (hand formulas)

from contopt.errors import ConfigError
from contopt.material.energy import energy_of_F, invariants, mooney_rivlin_energy
from contopt.material.hyperelastic import MooneyRivlin, neo_hookean, simp

E0, NU0 = 2.0, 0.3

MATERIALS = {
    "neo-hookean": neo_hookean(E0, NU0),
    "mooney-rivlin": MooneyRivlin.from_E_nu(E0, NU0, b_fraction=0.4),
}


@pytest.fixture(params=sorted(MATERIALS))
def mat(request):
    return MATERIALS[request.param]


# ------------------------------------------------------------------ helpers


def random_rotation(rng):
    q, r = np.linalg.qr(rng.standard_normal((3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


def sample_F(rng):
    """Deformation gradients with det F > 0: a moderate general one and a large-strain one."""
    F_small = np.eye(3) + 0.25 * rng.standard_normal((3, 3))
    assert np.linalg.det(F_small) > 0.2
    stretches = np.array([0.5, 1.8, 1.1])
    F_large = random_rotation(rng) @ np.diag(stretches) @ random_rotation(rng)
    return [F_small, F_large]


_JIT = {}


def _jitted(mat, kind):
    """jit-compiled psi / grad psi / hessian psi of one material (eager JAX is slow in FD loops)."""
    key = (id(mat), kind)
    if key not in _JIT:
        f = {"psi": mat.psi, "P": jax.grad(mat.psi), "A": jax.jacfwd(jax.grad(mat.psi)), "H": jax.hessian(mat.psi)}[
            kind
        ]
        _JIT[key] = jax.jit(f)
    return _JIT[key]


def psi_np(mat, F):
    return float(_jitted(mat, "psi")(jnp.asarray(F)))


def P_ad(mat, F):
    return np.asarray(_jitted(mat, "P")(jnp.asarray(F)))


def cauchy_ad(mat, F):
    F = np.asarray(F, float)
    return P_ad(mat, F) @ F.T / np.linalg.det(F)


# ------------------------------------------------------- derivatives vs FD
def fd_gradient(f, F, h):
    out = np.zeros((3, 3) + np.shape(f(F)))
    for i in range(3):
        for j in range(3):
            dF = np.zeros((3, 3))
            dF[i, j] = h
            out[i, j] = (np.asarray(f(F + dF)) - np.asarray(f(F - dF))) / (2.0 * h)
    return out


def test_first_piola_matches_finite_differences_of_psi(mat, rng):
    for F in sample_F(rng):
        P = P_ad(mat, F)
        P_fd = fd_gradient(lambda G: psi_np(mat, G), F, 1e-6)
        assert rel_err(P, P_fd) <= 1e-6


def test_elasticity_tensor_matches_finite_differences_of_P(mat, rng):
    for F in sample_F(rng):
        A = np.asarray(_jitted(mat, "A")(jnp.asarray(F)))  # [i, J, k, L] = dP_iJ / dF_kL
        A_fd = fd_gradient(lambda G: P_ad(mat, G), F, 1e-6)  # [k, L, i, J]
        assert rel_err(A, A_fd.transpose(2, 3, 0, 1)) <= 1e-6
        # hyperelastic: major symmetry
        assert rel_err(A, A.transpose(2, 3, 0, 1)) <= 1e-12


def test_psi_from_invariants_matches_direct_formula(mat, rng):
    """psi(F) against a direct numpy evaluation of the paper's C.1-C.3 from C = F^T F."""
    for F in sample_F(rng):
        C = F.T @ F
        J = np.linalg.det(F)
        Cbar = J ** (-2.0 / 3.0) * C
        I1b = np.trace(Cbar)
        I2b = 0.5 * (I1b**2 - np.trace(Cbar @ Cbar))
        ref = 0.5 * mat.kappa * np.log(J) ** 2 + mat.A * (I1b - 3) + mat.B * (I2b - 3)
        assert psi_np(mat, F) == pytest.approx(ref, rel=1e-12)
        assert float(energy_of_F(mooney_rivlin_energy, jnp.asarray(F), jnp.asarray(mat.params))) == pytest.approx(
            ref, rel=1e-12
        )
        I1, I2, J_ = (float(x) for x in invariants(jnp.asarray(F)))
        assert I1 == pytest.approx(np.trace(C), rel=1e-13)
        assert I2 == pytest.approx(0.5 * (np.trace(C) ** 2 - np.trace(C @ C)), rel=1e-13)
        assert J_ == pytest.approx(J, rel=1e-13)


def test_general_cauchy_hand_formula_matches_ad(mat, rng):
    for F in sample_F(rng):
        assert rel_err(cauchy_ad(mat, F), cauchy_hand(mat, F)) <= 1e-10


# ------------------------------------------------------ analytic stresses
@pytest.mark.parametrize("l1", [1.5, 0.6])
def test_uniaxial_principal_stresses_by_hand(mat, l1):
    l2_free = uniaxial_lateral_stretch(mat, l1)
    for l2 in (0.9, 1.2, l2_free):
        F = np.diag([l1, l2, l2])
        sig = cauchy_ad(mat, F)
        ref = np.diag(principal_cauchy(mat, [l1, l2, l2]))
        assert rel_err(sig, ref) <= 1e-8
    # at the brentq stretch the lateral stresses vanish and the axial one has the sign of the load
    sig = cauchy_ad(mat, np.diag([l1, l2_free, l2_free]))
    assert np.abs(sig[1:, 1:]).max() <= 1e-10 * mat.mu
    assert np.sign(sig[0, 0]) == np.sign(l1 - 1.0)
    assert (l2_free < 1.0) == (l1 > 1.0)


def test_uniaxial_curve_small_strain_gives_E_and_nu(mat):
    """Independent check of the hand curve: tangent slope E and contraction ratio nu at l1 -> 1."""
    eps = 1e-6
    l2 = uniaxial_lateral_stretch(mat, 1.0 + eps)
    s11 = principal_cauchy(mat, [1.0 + eps, l2, l2])[0]
    assert s11 / eps == pytest.approx(E0, rel=1e-5)
    assert -(l2 - 1.0) / eps == pytest.approx(NU0, rel=1e-5)


@pytest.mark.parametrize("b_fraction", [0.0, 0.4])
@pytest.mark.parametrize("l1", [1.5, 0.6])
def test_uniaxial_curve_nearly_incompressible_limit(b_fraction, l1):
    """kappa -> inf: sigma = 2 (l^2 - 1/l)(A + B / l), the incompressible Mooney-Rivlin curve."""
    m = MooneyRivlin.from_E_nu(1.0, 0.4999999, b_fraction=b_fraction)
    l2 = uniaxial_lateral_stretch(m, l1)
    assert l2 == pytest.approx(l1**-0.5, rel=1e-5)
    s11 = principal_cauchy(m, [l1, l2, l2])[0]
    assert s11 == pytest.approx(2.0 * (l1**2 - 1.0 / l1) * (m.A + m.B / l1), rel=1e-5)


def test_simple_shear_by_hand(mat):
    g = 0.8
    F = np.eye(3)
    F[0, 1] = g
    b = F @ F.T
    I1 = np.trace(b)
    s = 2.0 * (mat.A * b + mat.B * (I1 * b - b @ b))
    ref = s - np.trace(s) / 3.0 * np.eye(3)
    sig = cauchy_ad(mat, F)
    assert rel_err(sig, ref) <= 1e-8
    assert sig[0, 1] == pytest.approx(2.0 * (mat.A + mat.B) * g, rel=1e-12)
    assert sig[0, 1] == pytest.approx(mat.mu * g, rel=1e-12)
    # normal stress differences (Poynting effect): s11 - s22 = 2 (A + B) g^2, s22 - s33 = -2 B g^2
    assert sig[0, 0] - sig[1, 1] == pytest.approx(2.0 * (mat.A + mat.B) * g**2, rel=1e-10)
    assert sig[1, 1] - sig[2, 2] == pytest.approx(-2.0 * mat.B * g**2, abs=1e-12 * mat.mu)


# ----------------------------------------------------- small-strain limit
def test_small_strain_tensor_is_isotropic_C7(mat):
    A4 = np.asarray(_jitted(mat, "H")(jnp.eye(3)))
    d = np.eye(3)
    mu = 2.0 * (mat.A + mat.B)
    lam = mat.kappa - 2.0 * mu / 3.0
    ref = mu * (np.einsum("ik,jl->ijkl", d, d) + np.einsum("il,jk->ijkl", d, d)) + lam * np.einsum("ij,kl->ijkl", d, d)
    assert np.abs(A4 - ref).max() <= 1e-10 * np.abs(ref).max()
    # zero stress in the reference state
    assert np.abs(P_ad(mat, np.eye(3))).max() <= 1e-14 * mu


@pytest.mark.parametrize("E,nu,bf", [(2.0, 0.3, 0.0), (210e3, 0.49, 0.25), (1.0, -0.5, 1.0), (3.0, 0.0, 0.5)])
def test_from_E_nu_round_trip(E, nu, bf):
    m = MooneyRivlin.from_E_nu(E, nu, b_fraction=bf)
    mu = E / (2.0 * (1.0 + nu))
    assert m.youngs_modulus == pytest.approx(E, rel=1e-12)
    assert m.poisson_ratio == pytest.approx(nu, rel=1e-12, abs=1e-14)
    assert m.kappa == pytest.approx(E / (3.0 * (1.0 - 2.0 * nu)), rel=1e-12)
    assert 2.0 * (m.A + m.B) == pytest.approx(mu, rel=1e-12)
    assert m.mu == pytest.approx(mu, rel=1e-12)
    assert m.lame_lambda == pytest.approx(E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)), rel=1e-12, abs=1e-12 * E)
    assert m.B == pytest.approx(bf * mu / 2.0, rel=1e-12, abs=0.0)
    assert np.array_equal(m.params, np.array([m.kappa, m.A, m.B]))
    n = neo_hookean(E, nu)
    assert n.B == 0.0 and n.mu == pytest.approx(mu, rel=1e-12)


# --------------------------------------------------------------- bad input
@pytest.mark.parametrize("nu", [0.5, 0.7, -1.0, float("nan")])
def test_bad_poisson_ratio(nu):
    with pytest.raises(ConfigError, match="nu"):
        MooneyRivlin.from_E_nu(1.0, nu)
    with pytest.raises(ConfigError, match="nu"):
        neo_hookean(1.0, nu)


@pytest.mark.parametrize("E", [0.0, -1.0, float("nan")])
def test_bad_youngs_modulus(E):
    with pytest.raises(ConfigError, match=r"\bE\b"):
        MooneyRivlin.from_E_nu(E, 0.3)


@pytest.mark.parametrize(
    "kwargs,name",
    [
        (dict(kappa=1.0, A=-0.1, B=0.2), "A"),
        (dict(kappa=1.0, A=0.1, B=-0.2), "B"),
        (dict(kappa=1.0, A=0.0, B=0.0), "A"),
        (dict(kappa=0.0, A=0.1, B=0.0), "kappa"),
        (dict(kappa=-2.0, A=0.1, B=0.0), "kappa"),
        (dict(kappa=1.0, A=float("inf"), B=0.0), "A"),
        (dict(kappa=1.0, A=0.1, B=0.0, mass_density=-1.0), "mass_density"),
    ],
)
def test_bad_material_constants(kwargs, name):
    with pytest.raises(ConfigError, match=rf"\b{name}\b"):
        MooneyRivlin(**kwargs)


def test_bad_b_fraction():
    with pytest.raises(ConfigError, match="b_fraction"):
        MooneyRivlin.from_E_nu(1.0, 0.3, b_fraction=1.5)


# -------------------------------------------------------------------- SIMP
def test_simp_values():
    nu0, p = 1e-2, 3.0
    assert simp(0.0) == pytest.approx(nu0, rel=1e-15)
    assert simp(1.0) == pytest.approx(1.0, rel=1e-15)
    assert simp(0.5) == pytest.approx((1.0 - nu0) * 0.5**p + nu0, rel=1e-15)
    assert simp(0.5) == pytest.approx(0.13375, rel=1e-15)
    assert simp(0.5, p=2.0, nu0=0.1) == pytest.approx(0.9 * 0.25 + 0.1, rel=1e-15)
    assert simp(0.0, p=5.0, nu0=1e-3) == pytest.approx(1e-3, rel=1e-15)
    x = np.array([0.0, 0.5, 1.0])
    np.testing.assert_allclose(simp(x), (1 - nu0) * x**p + nu0, rtol=1e-15)
    # differentiable (used in sensitivities): d simp / d nu = p (1 - nu0) nu^(p-1)
    assert float(jax.grad(simp)(0.5)) == pytest.approx(p * (1 - nu0) * 0.25, rel=1e-14)


def test_any_object_with_the_material_protocol_is_a_material():
    from dataclasses import dataclass

    from contopt.assembly.model import Body, Dirichlet, Model, Traction
    from contopt.material import Material
    from contopt.mesh.generators import box
    from contopt.solve.linear import LinearSolverOptions
    from contopt.solve.static import solve_static

    @dataclass(frozen=True)
    class Rubber:  # a user's material: its own class, the Mooney-Rivlin energy with fixed constants
        energy = staticmethod(mooney_rivlin_energy)
        params = np.array([5.0, 0.4, 0.1])
        youngs_modulus = 9.0 * 5.0 * 1.0 / (15.0 + 1.0)
        poisson_ratio = (15.0 - 2.0) / (2.0 * 16.0)
        mass_density = 0.0

    assert isinstance(Rubber(), Material)
    mesh = box((1.0, 1.0, 1.0), (2, 2, 2))

    def stretch(material):
        model = Model(
            bodies=(Body("b", mesh, material),),
            dirichlet=(Dirichlet("b", "xmin", "xyz"),),
            loads=(Traction("b", "xmax", (0.05, 0.0, 0.0)),),
        )
        # every solve exact (a factor kept from the first run would precondition the second's)
        return solve_static(model, linear=LinearSolverOptions(factor_reuse=False)).u

    np.testing.assert_array_equal(stretch(Rubber()), stretch(MooneyRivlin(kappa=5.0, A=0.4, B=0.1)))
    with pytest.raises(ConfigError, match="material must be a material"):
        Body("b", mesh, {"E": 1.0})
