"""The assembled contact system: exact derivatives, invariance, Newton/ALM behaviour, validation.

* The contact residual is the gradient of the contact potential and the
  tangent the derivative of the residual (central finite differences along
  random directions), for penalty and augmented-Lagrangian multipliers, on
  configurations with large sliding offsets: rotated non-matching meshes
  (overlap polygons of 3 to 8 vertices), a curved mortar surface and warped
  facets. Each check first makes sure that the configuration is smooth within
  +-h: no node at the kink of ``max(0, p - eps gbar)``, same active set, same
  facet pairs and same segmentation topology.
* Rigid motions of the whole configuration leave the pressures unchanged.
* Newton converges quadratically inside each augmentation.
* Validation errors name the problem.
* Inactive nodes and exactly touching bodies never make the system singular.
"""

import numpy as np
import pytest
import scipy.sparse as sp

from contopt.assembly.model import Body, Dirichlet, Model, Traction
from contopt.cases.die_slab import die_slab
from contopt.contact.enforcement import node_terms
from contopt.contact.interface import ContactInterface
from contopt.contact.laws import AugmentedLagrangian, Penalty, law_named
from contopt.contact.search import candidate_pairs, facing_filter
from contopt.contact.segment import segment_pairs
from contopt.errors import ConfigError, MeshError
from contopt.material import neo_hookean
from contopt.mesh.core import Mesh
from contopt.mesh.generators import box, cylinder_shell_sector
from contopt.solve.newton import NewtonOptions
from contopt.solve.static import AugmentationOptions, solve_static
from contopt.solve.system import System

H = 1.0 / 3.0  # facet size of the flat configurations
FD_STEP = 1e-6  # finite-difference step (directions are scaled to unit max-norm)
FD_RTOL = 1e-6


def _rotz(deg):
    c, s = np.cos(np.deg2rad(deg)), np.sin(np.deg2rad(deg))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _rotation(axis, deg):
    """Rodrigues rotation about ``axis`` by ``deg`` degrees."""
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    a = np.deg2rad(deg)
    return np.eye(3) + np.sin(a) * K + (1 - np.cos(a)) * K @ K


def _perturbed(mesh: Mesh, amplitude: float, rng) -> Mesh:
    """The mesh with every node moved randomly by up to ``amplitude`` per component (warped facets)."""
    pts = mesh.points + amplitude * rng.uniform(-1.0, 1.0, mesh.points.shape)
    return Mesh(pts, mesh.cells, mesh.node_sets, mesh.facet_sets)


# ------------------------------------------------------------------ configurations
def _rotated_blocks(law="penalty"):
    """Upper block 4 x 4 facets of size H rotated 17 degrees in-plane (nonmortar, bottom face)
    on a larger 8 x 8 lower block (mortar, top face): equal facet sizes, so that nearly
    concentric rotated pairs give octagons and heptagons."""
    lower = box((8 * H, 8 * H, 0.5), (8, 8, 1), origin=(-4 * H, -4 * H, -0.5))
    upper = box((4 * H, 4 * H, 0.4), (4, 4, 1), origin=(-0.5, -0.5, 0.0)).transformed(_rotz(17.0))
    return Model(
        bodies=(Body("up", upper, neo_hookean(1.0, 0.3)), Body("lo", lower, neo_hookean(2.0, 0.3))),
        interfaces=(ContactInterface(("up", "zmin"), ("lo", "zmax"), law=law_named(law, eps=50.0)),),
    )


def _curved_die():
    """A cylindrical shell sector (mortar, outer surface) on a block (nonmortar, top face)."""
    block = box((2.0, 1.4, 0.5), (6, 4, 1), origin=(-1.0, -0.7, -0.5))
    die = cylinder_shell_sector(
        radius=1.5,
        arc=np.deg2rad(80.0),
        width=1.2,
        thickness=0.2,
        divisions=(10, 4, 1),
        center=(0.0, 0.0, 1.5),
        axis="y",
        mid_angle=-np.pi / 2,
    )
    return Model(
        bodies=(Body("block", block, neo_hookean(1.0, 0.3)), Body("die", die, neo_hookean(5.0, 0.3))),
        interfaces=(ContactInterface(("block", "zmax"), ("die", "outer"), law=AugmentedLagrangian(eps=30.0)),),
    )


def _warped_blocks(rng):
    """Non-matching blocks (4 x 4 on 7 x 7 facets) with every node moved randomly: warped facets."""
    lower = _perturbed(box((2.0, 2.0, 0.5), (7, 7, 1), origin=(-1.0, -1.0, -0.5)), 0.02, rng)
    upper = _perturbed(box((4 * H, 4 * H, 0.4), (4, 4, 1), origin=(-2 * H, -2 * H, 0.0)), 0.02, rng)
    return Model(
        bodies=(Body("up", upper, neo_hookean(1.0, 0.3)), Body("lo", lower, neo_hookean(2.0, 0.3))),
        interfaces=(ContactInterface(("up", "zmin"), ("lo", "zmax"), law=AugmentedLagrangian(eps=50.0)),),
    )


def _body_motion(model, name, u, shift, tilt_x=0.0, tilt_y=0.0):
    """Add to u a translation ``shift`` of body ``name`` plus a vertical tilt ``tilt_x X + tilt_y Y``."""
    i = model.body_index(name)
    start = sum(b.mesh.n_nodes for b in model.bodies[:i])
    X = model.bodies[i].mesh.points
    U = u.reshape(-1, 3)
    U[start : start + len(X)] += np.asarray(shift, float)
    U[start : start + len(X), 2] += tilt_x * X[:, 0] + tilt_y * X[:, 1]
    return u


def _configuration(kind, rng):
    """(model, u): an active contact state with sliding, a tilt (active and open nodes) and noise."""
    if kind == "rotated":
        model = _rotated_blocks()
        # in-plane noise small enough to keep the heptagons (a band about 0.01 wide of
        # offsets of nearly concentric pairs): this slide has all of 3..8 vertices
        n = sum(b.mesh.n_nodes for b in model.bodies)
        u = (rng.standard_normal((n, 3)) * [1e-4, 1e-4, 1e-3]).ravel()
        # slide by more than a facet; the tilt penetrates one side and opens the other
        u = _body_motion(model, "up", u, (H + 0.01, -H + 0.2713, -0.012), tilt_x=0.03)
    elif kind == "curved":
        model = _curved_die()
        u = 1e-3 * rng.standard_normal(3 * sum(b.mesh.n_nodes for b in model.bodies))
        # the die rolls 0.37 along x (more than a facet) and is pressed 0.03 into the block
        u = _body_motion(model, "die", u, (0.37, 0.05, -0.03))
    elif kind == "warped":
        model = _warped_blocks(rng)
        u = 1e-3 * rng.standard_normal(3 * sum(b.mesh.n_nodes for b in model.bodies))
        u = _body_motion(model, "up", u, (0.41, -0.23, -0.005), tilt_y=0.06)
    else:
        raise ValueError(kind)
    return model, u


def _segmentation(contact, u):
    """The facet pairs and their segmentation, as the contact evaluation computes them."""
    block = contact.blocks[0]
    x = contact.X + u.reshape(-1, 3)
    x_nm, x_m = x[block.nm_facet_nodes], x[block.m_facet_nodes]
    pairs = candidate_pairs(x_nm, x_m, block.skin)
    pairs = facing_filter(x_nm, x_m, pairs, block.interface.max_angle_deg, skin=block.skin)
    seg = segment_pairs(x_nm[pairs[:, 0]], x_m[pairs[:, 1]])
    return pairs, seg


def _multipliers(contact, u, law, rng):
    """The law states with zero (penalty) or random positive pressures on about half of the
    nonmortar nodes (ALM), kept away from the kink ``p = eps gbar`` at u."""
    block = contact.blocks[0]
    if law == "penalty":
        return contact.start_states()
    scale = 0.01 * block.eps * block.h
    p = rng.uniform(0.2, 1.0, block.n_nodes) * scale
    p[rng.random(block.n_nodes) < 0.5] = 0.0
    res = contact.evaluate(u, contact.start_states((p,)), tangent=False).results[0]
    trial = p - block.eps * res.g / np.where(res.has_overlap, res.a, 1.0)
    p[res.has_overlap & (np.abs(trial) < 0.1 * scale)] += 0.3 * scale
    return contact.start_states((p,))


def _contact_dofs(contact):
    block = contact.blocks[0]
    nodes = np.unique(np.concatenate([block.nm_facet_nodes.ravel(), block.m_facet_nodes.ravel()]))
    return (3 * nodes[:, None] + np.arange(3)).ravel()


def _assert_smooth(contact, u, p, directions, step):
    """No node within reach of the kink, same active set, pairs and topology at u +- step v."""
    block = contact.blocks[0]
    ev = contact.evaluate(u, p, tangent=False)
    res = ev.results[0]
    has = res.has_overlap
    trial = p[0].p[has] - block.eps * res.g[has] / res.a[has]
    # the trial pressure moves by about eps * step within +-step; stay far from zero
    assert np.abs(trial).min() > 100 * block.eps * step, np.abs(trial).min()
    pairs0, seg0 = _segmentation(contact, u)
    for v in directions:
        for s in (step, -step):
            w = u + s * v
            r = contact.evaluate(w, p, tangent=False).results[0]
            np.testing.assert_array_equal(r.has_overlap, has)
            np.testing.assert_array_equal(r.lam > 0, res.lam > 0)
            pairs, seg = _segmentation(contact, w)
            np.testing.assert_array_equal(pairs, pairs0)
            np.testing.assert_array_equal(seg.topo, seg0.topo)
    return res


def _check_derivatives(evaluate, u, directions, step):
    """Central differences of the energy against r.v and of the residual against K v."""
    ev = evaluate(u, True)
    for v in directions:
        ep, em = evaluate(u + step * v, False), evaluate(u - step * v, False)
        de = (ep.energy - em.energy) / (2 * step)
        rv = float(ev.r @ v)
        assert abs(de - rv) <= FD_RTOL * abs(rv), (de, rv)
        dr = (ep.r - em.r) / (2 * step)
        Kv = ev.K @ v
        assert np.linalg.norm(dr - Kv) <= FD_RTOL * np.linalg.norm(Kv), np.linalg.norm(dr - Kv) / np.linalg.norm(Kv)
    # the tangent of a potential is symmetric
    K = ev.K
    assert abs(K - K.T).max() <= 1e-12 * abs(K).max()
    return ev


@pytest.mark.parametrize(
    "kind,law",
    [
        ("rotated", "penalty"),
        ("rotated", "alm"),
        ("curved", "penalty"),
        ("curved", "alm"),
        ("warped", "penalty"),
        ("warped", "alm"),
    ],
)
def test_contact_residual_and_tangent_match_finite_differences(kind, law, rng):
    model, u = _configuration(kind, rng)
    contact = System.of(model).contact
    p = _multipliers(contact, u, law, rng)
    dofs = _contact_dofs(contact)
    directions = []
    for _ in range(3):
        v = np.zeros(contact.n_dofs)
        v[dofs] = rng.uniform(-1.0, 1.0, dofs.size)
        directions.append(v)
    res = _assert_smooth(contact, u, p, directions, FD_STEP)
    # a mixed state: active nodes and open nodes with overlap
    assert res.n_active >= 3
    assert np.count_nonzero(res.has_overlap & (res.lam == 0)) >= 2
    _check_derivatives(lambda w, tangent: contact.evaluate(w, p, tangent), u, directions, FD_STEP)
    if kind == "rotated":
        pairs, seg = _segmentation(contact, u)
        counts = np.bincount(seg.n_vertices[seg.active], minlength=9)
        assert np.all(counts[3:9] > 0), counts  # triangles up to octagons
    if kind == "warped":
        x = contact.X + u.reshape(-1, 3)
        for facets in (contact.blocks[0].nm_facet_nodes, contact.blocks[0].m_facet_nodes):
            f = x[facets]
            n = np.cross(f[:, 1] - f[:, 0], f[:, 2] - f[:, 0])
            n /= np.linalg.norm(n, axis=1, keepdims=True)
            warp = np.abs(np.einsum("ij,ij->i", f[:, 3] - f[:, 0], n))
            assert np.median(warp) > 1e-2 * H


def test_problem_tangent_with_bulk_matches_finite_differences(rng):
    model, u = _configuration("rotated", rng)
    prob = System.of(model)
    p = _multipliers(prob.contact, u, "alm", rng)
    directions = [rng.uniform(-1.0, 1.0, prob.disc.n_dofs) for _ in range(2)]
    _assert_smooth(prob.contact, u, p, directions, FD_STEP)
    ev = _check_derivatives(
        lambda w, tangent: prob.evaluate(w, 1.0, prob.disc.layout(), p, tangent), u, directions, FD_STEP
    )
    # the contact part is a genuine contribution of the total
    ec = prob.contact.evaluate(u, p)
    assert np.linalg.norm(ec.r) > 1e-3 * np.linalg.norm(ev.r)
    np.testing.assert_allclose(ev.K_free.toarray(), ev.K[prob.disc.free][:, prob.disc.free].toarray(), atol=0)


# --------------------------------------------------------------------------- invariance
def _pressed_blocks(R=None, t=None):
    """The rotated-blocks pair (penalty), rigidly moved by (R, t): the upper block's top is pushed
    down with a tilt (one side stays open) and sideways, the lower block's bottom is fixed."""
    R = np.eye(3) if R is None else R
    t = np.zeros(3) if t is None else t
    base = _rotated_blocks("penalty")
    up, lo = (b.mesh.transformed(R, t) for b in base.bodies)

    def push(X, load):  # in the moved frame: rotate the reference, push, rotate back
        Y = (X - t) @ R
        d = np.stack([np.full(len(Y), 0.02), np.full(len(Y), -0.01), -0.01 - 0.03 * Y[:, 0]], axis=1)
        return load * d @ R.T

    return Model(
        bodies=(Body("up", up, base.bodies[0].material), Body("lo", lo, base.bodies[1].material)),
        dirichlet=(Dirichlet("up", "zmax", "xyz", push), Dirichlet("lo", "zmin", "xyz", 0.0)),
        interfaces=base.interfaces,
    )


R_RIGID = _rotation((1.0, -2.0, 0.5), 40.0)
T_RIGID = np.array([3.0, -2.0, 5.0])


def test_the_solvers_evaluation_holds_the_free_blocks_of_the_whole_tangent(rng):
    """Newton and the adjoint evaluate with ``full=False``: ``K_free`` and ``K_fc`` (free rows,
    constrained columns: what a prescribed increment needs) are the blocks of the whole tangent,
    the contact's coupling to a support held fixed included, and the whole one is not kept."""
    upper = box((1.0, 1.0, 0.5), (3, 3, 2), origin=(0.0, 0.0, 0.98))
    lower = box((1.4, 1.4, 1.0), (4, 4, 1), origin=(-0.2, -0.2, 0.0))
    model = Model(
        bodies=(Body("top", upper, neo_hookean(1.0, 0.3)), Body("base", lower, neo_hookean(5.0, 0.3))),
        dirichlet=(Dirichlet("top", "zmax", "xyz"), Dirichlet("base", "all")),
        interfaces=(ContactInterface(("top", "zmin"), ("base", "zmax"), law="penalty"),),
    )
    prob = System.of(model)
    u = np.zeros(prob.disc.n_dofs)
    u[prob.disc.body_slice("top")] = rng.uniform(-0.01, 0.01, upper.n_nodes * 3) - np.tile(
        [0.0, 0.0, 0.02], upper.n_nodes
    )
    whole = prob.evaluate(u, 1.0, prob.disc.layout(), prob.start_states())
    part = prob.evaluate(u, 1.0, prob.disc.layout(), prob.start_states(), full=False)
    assert part.contact[0].n_active > 0
    free, fixed = prob.disc.free, prob.disc.constrained
    K = whole.K
    assert abs(part.K_free - K[free][:, free]).max() == 0.0
    contact_fc = prob.contact.evaluate(u, prob.start_states()).K[free][:, fixed]
    assert abs(contact_fc).max() > 0  # the contact couples free nodes to the fixed base
    assert abs(part.K_fc - K[free][:, fixed]).max() == 0.0
    assert part.K_terms is None
    with pytest.raises(ValueError, match="full=True"):
        part.K_dot(u)


def test_rigid_motion_leaves_contact_evaluation_unchanged(rng):
    model, u = _configuration("rotated", rng)
    moved = Model(
        bodies=tuple(Body(b.name, b.mesh.transformed(R_RIGID, T_RIGID), b.material) for b in model.bodies),
        interfaces=model.interfaces,
    )
    c0, c1 = System.of(model).contact, System.of(moved).contact
    p = _multipliers(c0, u, "alm", rng)
    e0 = c0.evaluate(u, p)
    e1 = c1.evaluate((u.reshape(-1, 3) @ R_RIGID.T).ravel(), p)
    r0, r1 = e0.results[0], e1.results[0]
    assert r0.n_active >= 3
    for name in ("g", "a", "lam"):
        a0, a1 = getattr(r0, name), getattr(r1, name)
        np.testing.assert_allclose(a1, a0, rtol=0, atol=1e-12 * np.abs(a0).max(), err_msg=name)
    np.testing.assert_allclose(e1.energy, e0.energy, rtol=1e-12)
    rot = (e0.r.reshape(-1, 3) @ R_RIGID.T).ravel()
    np.testing.assert_allclose(e1.r, rot, rtol=0, atol=1e-12 * np.abs(rot).max())
    Rb = sp.kron(sp.identity(c0.n_dofs // 3), R_RIGID)
    K_rot = Rb @ e0.K @ Rb.T
    assert abs(e1.K - K_rot).max() <= 1e-12 * abs(K_rot).max()


def test_rigid_motion_leaves_solved_pressures_unchanged():
    newton = NewtonOptions(rtol=1e-12, utol=1e-10)
    s0 = solve_static(_pressed_blocks(), newton=newton)
    s1 = solve_static(_pressed_blocks(R_RIGID, T_RIGID), newton=newton)
    lam0, lam1 = s0.contact[0].lam, s1.contact[0].lam
    assert np.count_nonzero(lam0) >= 5 and np.count_nonzero(s0.contact[0].has_overlap & (lam0 == 0)) >= 3
    np.testing.assert_allclose(lam1, lam0, rtol=0, atol=1e-10 * lam0.max())
    u_rot = (s0.u.reshape(-1, 3) @ R_RIGID.T).ravel()
    np.testing.assert_allclose(s1.u, u_rot, rtol=0, atol=1e-9 * np.abs(u_rot).max())


# --------------------------------------------------------------------------- Newton / ALM
def _orders(lg, low=1e-11, high=1e-2):
    """Observed orders ``log(r_k+1) / log(r_k)`` of the relative residuals ``r = |r_free| / r_ref``,
    over consecutive pairs that both lie in the asymptotic range [low, high]: above the
    round-off floor (about 1e-13 here) and past Newton's global phase. Unlike
    ``NewtonLog.convergence_rates`` this keeps ``residuals[0]``: after a multiplier update it is
    the start of the solve, not the ~0 residual before a prescribed jump."""
    rel = np.array(lg.residuals) / lg.r_ref
    return [np.log(b) / np.log(a) for a, b in zip(rel[:-1], rel[1:]) if low <= b and a <= high and low <= a]


def test_newton_is_quadratic_inside_every_augmentation():
    # every augmentation solved fully (inexact=0), so that each one shows its own convergence order.
    # The die rests on the slab, so both steps press: with the fitted die's gap the first step is
    # contact-free and the second's active set still changes close to convergence (one linear step)
    state = solve_static(
        die_slab(slab_divisions=(9, 4, 3), die="resting"),
        newton=NewtonOptions(n_steps=2, rtol=1e-12),
        augmentation=AugmentationOptions(inexact=0.0),
    )
    assert state.t == 1.0
    assert state.alm_updates > 0
    n_orders = 0
    for lg in state.logs:
        assert lg.converged, lg.summary()
        if lg.iterations < 3:
            continue
        orders = _orders(lg)
        n_orders += len(orders)
        assert min(orders, default=2.0) >= 1.7, (orders, lg.summary())
    assert n_orders >= 4
    # per load step: augmentations numbered 0, 1, ...; the multiplier change decreases
    steps = {}
    for lg in state.logs:
        steps.setdefault(lg.t, []).append(lg)
    assert sorted(steps) == [0.5, 1.0]
    for t, logs in steps.items():
        assert [lg.extra["alm_update"] for lg in logs] == list(range(len(logs)))
        dp = [lg.extra["pressure_change"] for lg in logs]
        assert all(b < a for a, b in zip(dp[:-1], dp[1:])), (t, dp)
    final = steps[1.0]
    assert len(final) >= 3
    assert final[-1].extra["pressure_change"] <= 1e-6 and final[-1].extra["penetration"] <= 1e-6
    assert final[-1].extra["pressure_change"] <= 1e-4 * final[0].extra["pressure_change"]


# --------------------------------------------------------------------------- validation
def _two_blocks(iface, lower_height=1.0):
    upper = box((1.0, 1.0, 0.5), (2, 2, 1), origin=(0.0, 0.0, lower_height))
    lower = box((1.0, 1.0, lower_height), (2, 2, 1))
    mat = neo_hookean(1.0, 0.3)
    return Model(bodies=(Body("up", upper, mat), Body("lo", lower, mat)), interfaces=(iface,))


def test_unknown_facet_set_is_named():
    with pytest.raises(MeshError, match="bottom_face"):
        _two_blocks(ContactInterface(("up", "bottom_face"), ("lo", "zmax")))
    with pytest.raises(MeshError, match="topp"):
        _two_blocks(ContactInterface(("up", "zmin"), ("lo", "topp")))


def test_same_body_on_both_sides_is_rejected():
    with pytest.raises(ConfigError, match="self-contact"):
        ContactInterface(("up", "zmin"), ("up", "zmax"))


def test_bad_enforcement_lists_the_choices():
    with pytest.raises(ConfigError) as info:
        ContactInterface(("up", "zmin"), ("lo", "zmax"), law="lagrange")
    assert "'alm'" in str(info.value) and "'penalty'" in str(info.value) and "lagrange" in str(info.value)


@pytest.mark.parametrize("law", [Penalty, AugmentedLagrangian])
@pytest.mark.parametrize("eps", [0.0, -1.0, float("nan"), float("inf"), "10"])
def test_non_positive_eps_is_rejected(law, eps):
    with pytest.raises(ConfigError, match="eps"):
        law(eps=eps)


def test_surfaces_that_do_not_face_each_other_are_rejected():
    # the lower block's bottom is 0.5 below the upper block's bottom: close, both facing down
    with pytest.raises(MeshError, match="face each other"):
        _two_blocks(ContactInterface(("up", "zmin"), ("lo", "zmin")), lower_height=0.5)
    # the correct pairing of the same bodies is accepted
    _two_blocks(ContactInterface(("up", "zmin"), ("lo", "zmax")), lower_height=0.5)


# --------------------------------------------------------------------------- inactive nodes
def test_partial_contact_under_prescribed_motion_solves():
    # a small tilted block pushed into a large one: most of the (nonmortar) large surface
    # never sees the mortar block, part of the overlap stays open
    tilt = _rotation((0.0, 1.0, 0.0), 4.0)
    upper = box((0.8, 0.8, 0.4), (3, 3, 1), origin=(-0.4, -0.4, 0.0)).transformed(tilt, (0.0, 0.0, 0.03))
    lower = box((2.0, 2.0, 0.5), (8, 8, 2), origin=(-1.0, -1.0, -0.5))
    model = Model(
        bodies=(Body("up", upper, neo_hookean(2.0, 0.3)), Body("lo", lower, neo_hookean(1.0, 0.3))),
        dirichlet=(Dirichlet("up", "zmax", "xyz", (0.0, 0.0, -0.06)), Dirichlet("lo", "zmin", "xyz", 0.0)),
        interfaces=(ContactInterface(("lo", "zmax"), ("up", "zmin"), law="alm"),),
    )
    state = solve_static(model, newton=NewtonOptions(n_steps=2))
    assert state.t == 1.0 and all(lg.converged for lg in state.logs)
    res = state.contact[0]
    assert res.n_active >= 3
    assert np.count_nonzero(~res.has_overlap) > res.has_overlap.sum()  # most of the surface is off
    assert np.count_nonzero(res.has_overlap & (res.lam == 0)) >= 1  # open nodes with overlap
    # the force through the contact balances: the reactions (= residual on the prescribed dofs)
    # of the two bodies are equal and opposite; the upper block is pushed down
    n_up = 3 * upper.n_nodes
    f_up, f_lo = state.reactions[:n_up].reshape(-1, 3).sum(0), state.reactions[n_up:].reshape(-1, 3).sum(0)
    assert f_up[2] < 0
    np.testing.assert_allclose(f_up + f_lo, 0.0, atol=1e-8 * abs(f_up[2]))


def test_exactly_touching_body_held_only_by_contact_solves():
    # the upper block rests on the lower one (gap exactly 0, zero pressure) and has no vertical
    # support except the contact: without the 'touch' rule the first tangent would be singular
    g = np.zeros(4)
    assert np.all(node_terms(g, np.ones(4), np.zeros(4), 10.0, touch=0.0).stiff == 0)
    assert np.all(node_terms(g, np.ones(4), np.zeros(4), 10.0, touch=1e-10).stiff > 0)
    load = 1e-3
    upper = box((1.0, 1.0, 0.5), (3, 3, 2), origin=(0.0, 0.0, 1.0))
    lower = box((1.6, 1.6, 1.0), (5, 5, 1), origin=(-0.3, -0.3, 0.0))
    lower = lower.transformed(_rotz(17.0), np.array([0.5, 0.5, 0.0]) - _rotz(17.0) @ [0.5, 0.5, 0.0])
    model = Model(
        bodies=(Body("up", upper, neo_hookean(1.0, 0.3)), Body("lo", lower, neo_hookean(1.0, 0.3))),
        dirichlet=(Dirichlet("up", "xmin", "x"), Dirichlet("up", "ymin", "y"), Dirichlet("lo", "zmin", "xyz")),
        loads=(Traction("up", "zmax", (0.0, 0.0, -load)),),
        interfaces=(ContactInterface(("up", "zmin"), ("lo", "zmax"), law="penalty"),),
    )
    prob = System.of(model)
    ev0 = prob.evaluate(np.zeros(prob.disc.n_dofs), 0.0, prob.disc.layout(), prob.start_states())
    assert ev0.contact[0].has_overlap.all() and np.all(ev0.contact[0].lam == 0)
    assert abs(ev0.K - prob.disc.evaluate(np.zeros(prob.disc.n_dofs), 0.0).K).max() > 0  # contact stiffness
    state = solve_static(prob, newton=NewtonOptions(rtol=1e-11))
    assert state.t == 1.0 and all(lg.converged for lg in state.logs)
    res = state.contact[0]
    assert np.all(res.lam > 0)
    # the contact carries the whole load (the rollers carry no vertical force): the vertical
    # contact forces on the upper and lower block are +-load
    rc = prob.contact.evaluate(state.u, state.laws, tangent=False).r.reshape(-1, 3)
    n_up = upper.n_nodes
    np.testing.assert_allclose(rc[:n_up, 2].sum(), -load, rtol=1e-9)
    np.testing.assert_allclose(rc[n_up:, 2].sum(), load, rtol=1e-9)
    # and the pressure integrates to it (up to the tilt of the slightly deformed surfaces)
    np.testing.assert_allclose(prob.contact.total_force(state.u, (res.lam,))[0], load, rtol=1e-6)


def test_an_update_of_one_interface_lets_the_solve_before_it_stop_early():
    """The solve's accuracy over interfaces (ContactDiscretization.early_stop): f > 0 from an interface
    whose update follows stands against another's 0 (converged, e.g. without contact), the smallest
    such f; 0 or no opinion everywhere: the Newton tolerances (None). Before, a converged interface
    beside the seam's other one made every solve of its updates run to the Newton tolerances."""
    from types import SimpleNamespace

    from contopt.contact.system import ContactDiscretization

    def early_stop(*factors):
        blocks = [SimpleNamespace(law=SimpleNamespace(early_stop=lambda r, s, h, f=f: f), h=1.0) for f in factors]
        n = len(factors)
        return ContactDiscretization.early_stop(SimpleNamespace(blocks=blocks), (None,) * n, (None,) * n)

    assert early_stop(0.0, 1e-4) == 1e-4
    assert early_stop(None, 1e-4, 3e-5) == 3e-5
    assert early_stop(0.0, None) is None and early_stop(None) is None and early_stop(0.0, 0.0) is None
