"""The aggregated von Mises stress: closed-form values, options, partials against central differences."""

import numpy as np
import pytest

from contopt.assembly.model import Body, Dirichlet, Model, Traction
from contopt.cases.two_blocks import two_blocks
from contopt.design.space import BoxRegion, cell_centroids
from contopt.errors import ConfigError
from contopt.material import neo_hookean
from contopt.mesh.generators import box
from contopt.responses import Fields, Stress, builtin
from contopt.solve.newton import NewtonOptions
from contopt.solve.static import solve_static
from contopt.solve.system import System

E, NU, T = 1.0, 0.3, 0.08  # modulus, Poisson ratio, nominal tension (per reference area)
RTOL = 1e-10  # Newton's relative residual tolerance of the bar's solve


@pytest.fixture(scope="module")
def bar():
    """A neo-Hookean bar in uniaxial tension: three symmetry planes, a traction on x = 2."""
    model = Model(
        bodies=(Body("bar", box((2.0, 1.0, 1.0), (4, 2, 2)), neo_hookean(E, NU)),),
        dirichlet=(Dirichlet("bar", "xmin", "x"), Dirichlet("bar", "ymin", "y"), Dirichlet("bar", "zmin", "z")),
        loads=(Traction("bar", "xmax", (T, 0.0, 0.0)),),
    )
    system = System.of(model)
    state = solve_static(system, newton=NewtonOptions(rtol=RTOL, n_steps=2))
    return system, state


def _stretches(system, state):
    X = system.disc.model.bodies[0].mesh.points
    x = X + state.u.reshape(-1, 3)
    corner = np.argmax(X.sum(axis=1))  # (2, 1, 1)
    return x[corner, 0] / 2.0, x[corner, 1] / 1.0


def test_uniaxial_tension_of_a_neo_hookean_bar_has_the_closed_form_von_mises_stress(bar):
    system, state = bar
    l, t = _stretches(system, state)
    J = l * t * t
    assert l > 1.05 and t < 0.99  # a finite strain, with lateral contraction
    # the Cauchy stress of uniaxial tension is T / t^2 (force over deformed area); of the energy
    # kappa/2 ln^2 J + mu/2 (I1bar - 3) its deviator gives von Mises = mu (l^2 - t^2) / J^(5/3)
    mu = E / (2 * (1 + NU))
    fields = Fields.from_state(system, state)
    tol = 100 * RTOL  # the residual Newton leaves, 1e-10 of the load, as a stress error, with margin
    for p in (2.0, 8.0, 20.0):  # a uniform stress: every p-norm returns it
        value = Stress(p=p, q=0.0).value(fields)
        assert value == pytest.approx(T / t**2, rel=tol)
        assert value == pytest.approx(mu * (l * l - t * t) / J ** (5 / 3), rel=tol)
    # relaxed on a uniform stiffness factor c: c^q times it; the cell values are the VTU's von Mises
    c = np.full(system.disc.n_cells, 0.3)
    grey = Fields(system=system, u=state.u, rho=c, lam=())
    assert Stress(q=0.5).value(grey) == pytest.approx(0.3**0.5 * T / t**2, rel=tol)
    from contopt.solve.fields import body_fields

    np.testing.assert_allclose(Stress(q=1.0).per_cell(grey), body_fields(system.disc, state.u, c, 0)[1]["von_mises"])


def test_ks_is_exact_on_a_uniform_stress_and_its_gap_below_two_levels_shrinks_like_log_share_over_s(bar):
    """The uniform bar: every sharpness returns its stress (the plain KS would add log(n_cells)/s). With the
    relaxed stress at two levels, a = s_bar on a volume share w (stiffness 1) and b = c^q s_bar elsewhere,
    the closed form is (1/s) log(w e^(s a) + (1 - w) e^(s b)): below the peak a by a gap that tends to
    log(1/w)/s as s grows."""
    system, state = bar
    fields = Fields.from_state(system, state)
    sbar = Stress(p=2.0, q=0.0).value(fields)
    tol = 100 * RTOL  # as in the closed-form test above: Newton's residual as a stress error
    for s in (1.0, 30.0, 1e4):  # s sbar up to ~1e3: the shift by the peak keeps exp finite
        assert Stress(q=0.0, aggregate="ks", sharpness=s).value(fields) == pytest.approx(sbar, rel=tol)
    n = system.disc.n_cells
    c, q = 0.2, 0.5
    rho = np.full(n, c)
    rho[: n // 4] = 1.0  # a quarter of the (equal) cells at full stiffness: w = 1/4
    grey = Fields(system=system, u=state.u, rho=rho, lam=())
    w, a, b = 0.25, sbar, c**q * sbar
    gaps = []
    for s in (10.0, 100.0, 1000.0):
        value = Stress(q=q, aggregate="ks", sharpness=s).value(grey)
        assert value == pytest.approx(np.log(w * np.exp(s * a) + (1 - w) * np.exp(s * b)) / s, rel=tol)
        assert value < a
        gaps.append((a - value) * s)
    # s (a - KS) -> log(1/w) as s grows: within (1-w)/w e^(-s (a - b)) of it
    assert gaps[-1] == pytest.approx(np.log(1 / w), rel=1e-6)
    assert gaps[0] < gaps[1] < gaps[2]


def test_the_p_norm_approaches_the_peak_from_below():
    system = System.of(two_blocks(divisions=4))
    rng = np.random.default_rng(1)
    u = 0.05 * rng.standard_normal(system.disc.n_dofs)
    lam = tuple(np.zeros(b.n_nodes) for b in system.contact.blocks)
    fields = Fields(system=system, u=u, rho=rng.uniform(0.2, 1.0, system.disc.n_cells), lam=lam)
    peak = Stress(bodies="block").per_cell(fields).max()
    values = [Stress(bodies="block", p=p).value(fields) for p in (2.0, 8.0, 32.0, 128.0)]
    assert all(a < b for a, b in zip(values, values[1:])) and values[-1] < peak
    assert values[-1] > 0.9 * peak
    # the KS function alike, within log(V / V_e)/s below the peak of cell e (the cells are equal here)
    cells = system.disc.cell_slice("block")
    n = cells.stop - cells.start
    for s in (10.0 / peak, 100.0 / peak, 1000.0 / peak):
        ks = Stress(bodies="block", aggregate="ks", sharpness=s).value(fields)
        assert peak - np.log(n) / s <= ks < peak


@pytest.fixture(scope="module")
def prob():
    return System.of(two_blocks(divisions=4))


HALF = BoxRegion((-np.inf, -np.inf, -np.inf), (0.5, np.inf, np.inf))  # the cells with centre x <= 0.5


@pytest.mark.parametrize(
    "response",
    [
        Stress(),
        Stress(bodies="block", p=2.0, q=0.0),
        Stress(bodies=("block",), p=12.0, q=1.0 / 6.0),
        Stress(bodies="block", p=6.0, region=HALF),
        Stress(aggregate="ks", sharpness=5.0),
        Stress(bodies="block", q=1.0 / 6.0, region=HALF, aggregate="ks", sharpness=40.0),
    ],
    ids=repr,
)
def test_partials_match_central_differences(prob, response):
    rng = np.random.default_rng(0)
    disc = prob.disc
    u = 0.02 * rng.standard_normal(disc.n_dofs)
    rho = rng.uniform(0.3, 1.0, disc.n_cells)
    lam = tuple(rng.uniform(0.0, 1.0, b.n_nodes) for b in prob.contact.blocks)
    f = Fields(system=prob, u=u, rho=rho, lam=lam)
    value, p = response.evaluate(f)
    assert value == pytest.approx(response.value(f), rel=1e-14)
    assert all(not np.any(d) for d in p.lam)  # the stress does not see the pressures
    du, drho, h = rng.standard_normal(u.size), rng.standard_normal(rho.size), 1e-6

    def at(s):
        return response.value(Fields(system=prob, u=u + s * du, rho=rho + s * drho, lam=lam))

    fd = (at(h) - at(-h)) / (2 * h)
    # central differences err by O(h^2 f''') + O(eps f / h): 1e-7 relative at h = 1e-6
    assert p.u @ du + p.rho @ drho == pytest.approx(fd, rel=1e-7)

    # each partial on its own (a broken rho or u partial fails here even if the sum happened to agree)
    def at_u(s):
        return response.value(Fields(system=prob, u=u + s * du, rho=rho, lam=lam))

    assert p.u @ du == pytest.approx((at_u(h) - at_u(-h)) / (2 * h), rel=1e-7)


def test_options_are_checked_with_the_fix_named(prob):
    for kw, match in (
        ({"p": 1.0}, r"Stress\.p must be a number >= 2"),
        ({"p": float("nan")}, r"Stress\.p must be"),
        ({"q": 1.5}, r"Stress\.q must be a number in \[0, 1\]"),
        ({"q": True}, r"Stress\.q must be"),
        ({"aggregate": "max"}, r"Stress\.aggregate must be one of \('pnorm', 'ks'\)"),
        ({"aggregate": "ks"}, r"Stress\.sharpness is needed with aggregate = \"ks\""),
        ({"aggregate": "ks", "sharpness": -1.0}, r"Stress\.sharpness must be a positive number"),
        ({"aggregate": "ks", "sharpness": 5.0, "p": 8.0}, r"Stress\.p is the p-norm's exponent"),
        ({"sharpness": 5.0}, r"Stress\.sharpness is the KS function's"),
    ):
        with pytest.raises(ConfigError, match=match):
            Stress(**kw)
    with pytest.raises(ConfigError, match="response body 'nope' is not a body of the model"):
        Stress(bodies="nope").check(prob)
    assert isinstance(builtin("stress", p=4.0), Stress)


@pytest.mark.parametrize("response", [Stress(), Stress(aggregate="ks", sharpness=10.0)], ids=repr)
def test_the_undeformed_state_has_no_stress_and_finite_partials(prob, response):
    lam = tuple(np.zeros(b.n_nodes) for b in prob.contact.blocks)
    f = Fields(system=prob, u=np.zeros(prob.disc.n_dofs), rho=np.ones(prob.disc.n_cells), lam=lam)
    value, p = response.evaluate(f)
    assert value < 1e-14 and np.all(np.isfinite(p.u)) and np.all(np.isfinite(p.rho))


def _random_fields(prob, seed=2):
    rng = np.random.default_rng(seed)
    lam = tuple(np.zeros(b.n_nodes) for b in prob.contact.blocks)
    u = 0.05 * rng.standard_normal(prob.disc.n_dofs)
    return Fields(system=prob, u=u, rho=rng.uniform(0.2, 1.0, prob.disc.n_cells), lam=lam)


def test_a_region_aggregates_the_cells_whose_centre_it_holds_only(prob):
    """The region's p-norm equals the p-norm of the per-cell stresses of its cells (computed by
    the VTU's path, not the response's kernel), and the stress outside the region does not enter."""
    f = _random_fields(prob)
    disc = prob.disc
    block = [b.name for b in disc.model.bodies].index("block")
    sl = disc.cell_slice(block)
    centres = cell_centroids(disc.model.bodies[block].mesh)
    inside = centres[:, 0] <= 0.5
    assert 0 < inside.sum() < len(inside)  # the box cuts the body
    p = 6.0
    cells = Stress(bodies="block", p=p).per_cell(f)[sl]
    volume = disc.blocks[block].volume
    expected = (np.sum(volume[inside] * cells[inside] ** p) / volume[inside].sum()) ** (1 / p)
    region = Stress(bodies="block", p=p, region=HALF)
    # the cell stresses of per_cell and of the kernel agree to round-off: 1e-12 relative
    assert region.value(f) == pytest.approx(expected, rel=1e-12)
    assert Stress(bodies="block", p=p).value(f) != pytest.approx(expected, rel=1e-3)  # the region matters here
    np.testing.assert_array_equal(region.per_cell(f)[sl][~inside], 0.0)
    _, partials = region.evaluate(f)
    outside = np.arange(disc.n_cells)[sl][~inside]
    np.testing.assert_array_equal(partials.rho[outside], 0.0)  # the cells outside do not move it


def test_a_region_without_cells_is_refused_with_the_fix_named(prob):
    empty = BoxRegion((10.0, 10.0, 10.0), (11.0, 11.0, 11.0))
    with pytest.raises(ConfigError, match="holds no cell centre of .*widen it"):
        Stress(bodies="block", region=empty).check(prob)
    with pytest.raises(ConfigError, match="Stress.region must be a callable"):
        Stress(region=[0.0, 1.0])
