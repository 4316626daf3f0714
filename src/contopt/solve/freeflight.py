"""The load steps of free flight in one: a leap to the last step before the bodies can touch.

A press whose tool starts above the part moves through free flight first: the fine die-slab's die
starts 0.4045 above the slab and moves 0.6 in 6 load steps, so 4 of them only translate the die,
one Newton iteration (assembly and a factorization) each, a third of the analysis. Where

* the system has contact, no friction (a path-dependent state) and no load (no traction, body force
  or soft support: the load steps then only move the prescribed dofs),
* every body's prescribed dofs move as one rigid translation, linearly in the load factor (a press;
  a rotating or path-following tool is left to the load steps), from zero at t = 0,

the state of each load step before the first touch is known: every body translated by its
prescribed translation times t, stress-free, no contact force. :func:`free_flight` finds the
last load factor the stepped path ends a step on while the contact surfaces' bounding boxes, each
swept along its translation, stay apart (a lower bound on the first touch: no gap closes before the
boxes do, and neither law acts at a positive gap), and :func:`contopt.solve.stepping.solve_load_steps`
takes one load step there instead of those steps. The steps in contact are then those of the stepped
path, from the same state: the same answer. The leap's converged state must be the translated one
(:meth:`Leap.lands`); where it is not (something loads the bodies after all) or the step fails,
the load steps start again from zero, as without the leap.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from contopt.solve.newton_options import NewtonOptions
from contopt.solve.system import System

#: prescribed values within this fraction of the largest one are the same translation (round-off)
SAME = 1e-12
#: the leap's state is the translated one to this fraction of the largest translation (Newton stops
#: at round-off on a free flight: the consistent predictor of a rigid translation is exact)
LANDING = 1e-8
#: the last step of the leap ends this fraction of the bound on the first touch before it
CLEARANCE = 1e-6


@dataclass(frozen=True, eq=False)
class Leap:
    """One load step over the free flight: to load factor ``t``, the end of the stepped path's
    ``skipped``-th step; the next step is ``dt`` long, as on the stepped path.

    expected : (n_dofs,) the state at ``t``: every body translated by ``t`` times its prescribed
        translation
    """

    t: float
    dt: float
    skipped: int
    expected: np.ndarray

    def lands(self, u: np.ndarray) -> bool:
        """Whether ``u`` (n_dofs,) is :attr:`expected` to :data:`LANDING` of the largest translation."""
        scale = float(np.abs(self.expected).max(initial=0.0))
        return bool(np.abs(np.asarray(u) - self.expected).max(initial=0.0) <= LANDING * scale)


def free_flight(system: System, newton: NewtonOptions) -> Leap | None:
    """The :class:`Leap` over the free flight of a solve from zero (module docstring), or None where
    there is none to take: ``newton.leap`` off, no contact, friction, a load (traction, body force or
    soft support), a prescribed motion other than rigid translations linear in t, or fewer than two
    load steps before the bound on the first touch."""
    disc = system.disc
    contact = system.contact
    if not newton.leap or contact is None or not system.has_contact or system.path_dependent:
        return None
    if disc.f_ext_unit[disc.free].any() or disc.has_volume_loads or disc.springs is not None:
        return None
    node_velocity = _translations(system)
    if node_velocity is None or not node_velocity.any():
        return None
    touch = min((_touch(contact.X, b, node_velocity) for b in contact.blocks), default=np.inf)
    steps = _stepped_path(newton)
    k = max((i for i, (t, _) in enumerate(steps) if t <= (1.0 - CLEARANCE) * touch), default=-1)
    if k < 1:  # a leap over one step is that step
        return None
    t, dt = steps[k]
    g1 = disc.prescribed(1.0)
    tol = SAME * float(np.abs(g1).max(initial=0.0))
    if any(np.abs(disc.prescribed(s) - s * g1).max(initial=0.0) > tol for s, _ in steps[: k + 1]):
        return None  # not linear in t up to the leap (a load path)
    return Leap(t=t, dt=dt, skipped=k + 1, expected=t * node_velocity.reshape(-1))


def _translations(system: System) -> np.ndarray | None:
    """(n_nodes_total, 3) each node's body's prescribed translation at t = 1 (zero in the directions the
    body has no prescribed dof), or None where some body's prescribed dofs do not move as one
    translation in each direction, or are not zero at t = 0."""
    disc = system.disc
    if np.abs(disc.prescribed(0.0)).max(initial=0.0) > 0.0:
        return None
    g1 = np.zeros(disc.n_dofs)
    g1[disc.constrained] = disc.prescribed(1.0)
    held = np.zeros(disc.n_dofs, bool)
    held[disc.constrained] = True
    tol = SAME * max(float(np.abs(g1).max(initial=0.0)), np.finfo(float).tiny)
    out = np.zeros((disc.n_dofs // 3, 3))
    for i, block in enumerate(disc.blocks):
        span = disc.body_slice(i)
        values, mask = g1[span].reshape(-1, 3), held[span].reshape(-1, 3)
        for k in range(3):
            v = values[mask[:, k], k]
            if v.size and np.ptp(v) > tol:
                return None
            out[block.node_offset : block.node_offset + block.n_nodes, k] = v[0] if v.size else 0.0
    return out


def _touch(X: np.ndarray, block, velocity: np.ndarray) -> float:
    """A lower bound on the load factor at which the two surfaces of ``block`` (an InterfaceBlock) can
    first touch, the nodes at ``X + t velocity`` ((n_nodes_total, 3) each): the last load factor at
    which their bounding boxes, each swept by its nodes' velocities, are still apart along some axis
    (0 where they overlap at the start, inf where they never meet)."""
    sides = []
    for facets in (block.nm_facet_nodes, block.m_facet_nodes):
        nodes = np.unique(np.asarray(facets).reshape(-1))
        x, v = X[nodes], velocity[nodes]
        sides.append((x.min(axis=0), x.max(axis=0), v.min(axis=0), v.max(axis=0)))
    best = 0.0
    for a, b in (sides, sides[::-1]):
        # side a below side b along each axis: apart while lo_b + t vlo_b > hi_a + t vhi_a
        (_, hi_a, _, vhi_a), (lo_b, _, vlo_b, _) = a, b
        gap, closing = lo_b - hi_a, vhi_a - vlo_b
        for g, c in zip(gap, closing):
            if g > 0:
                best = max(best, np.inf if c <= 0 else g / c)
    return best


def _stepped_path(newton: NewtonOptions) -> list:
    """``[(t, dt), ...]``: the load factor at the end of each step of the stepped path from zero where every
    step is easy (a free flight's: one Newton iteration), and the length of the step after it, in the
    arithmetic of :func:`contopt.solve.stepping.solve_load_steps` (the same floats)."""
    t, dt = 0.0, 1.0 / newton.n_steps
    max_dt = newton.max_step or dt
    out = []
    while t < 1.0 - 1e-12:
        dt = min(dt, 1.0 - t)
        t = t + dt
        dt = min(dt * newton.grow, max_dt)
        out.append((t, dt))
    return out
