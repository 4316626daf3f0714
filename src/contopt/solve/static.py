"""Quasi-static equilibrium of a model: load stepping + Newton (+ ALM augmentations for contact)."""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from contopt.assembly.model import Model
from contopt.assembly.system import Discretization, Evaluation, discretize
from contopt.errors import ConfigError
from contopt.solve.linear import LinearSolverOptions
from contopt.solve.newton import NewtonOptions, StepFailure, StepResult, newton_step, solve_load_steps

log = logging.getLogger(__name__)

#: normalized penetration (of the facet size) beyond which Newton drops the contact-geometry
#: part of the tangent (see Problem.evaluate); converged penetrations are ~1e-2 (penalty) or less
DEEP_PENETRATION = 0.1


@dataclass(frozen=True)
class AugmentationOptions:
    """Augmented-Lagrangian (Uzawa) loop around Newton.

    Converged when the largest multiplier change is below ``pressure_rtol``
    times the largest pressure, and the largest normalized penetration below
    ``gap_rtol`` times the median nonmortar facet size.

    ``intermediate``: ``"update"`` (default) makes one Newton solve and one
    multiplier update per intermediate load step and converges the
    augmentations at the final load factor only: elastic frictionless contact
    is path independent, so the intermediate states need not satisfy the
    constraint exactly, and this saves most of the Newton iterations.
    ``"converge"`` converges every load step (for load histories that are
    wanted accurately step by step, e.g. a force-displacement curve).

    Penalty growth (the method of multipliers' classical rule): when an
    update did not reduce the distance to convergence (the larger of the
    multiplier change and the penetration, each over its tolerance) by at
    least 4x, the interface's
    eps is multiplied by ``penalty_growth`` (up to ``max_penalty_scale`` times
    its initial value). Uzawa's linear rate ~ 1/(1 + eps/k) then improves
    quickly; Newton is not troubled because the state is already close.
    Set ``penalty_growth=1`` to keep eps fixed.

    ``inexact``: a Newton solve that a multiplier update will follow stops
    once ``|r| <= inexact * dp * r_ref`` (``dp``: the relative multiplier
    change the update is about to make): polishing an equilibrium that the
    update moves by much more is wasted work. The last augmentation is always
    solved to the Newton tolerances. ``inexact=0`` solves every augmentation
    fully.
    """

    max_updates: int = 50
    pressure_rtol: float = 1e-6
    gap_rtol: float = 1e-6
    intermediate: str = "update"
    penalty_growth: float = 10.0
    max_penalty_scale: float = 1e4
    inexact: float = 1e-2

    def __post_init__(self):
        if not isinstance(self.max_updates, int) or self.max_updates < 1:
            raise ConfigError(f"augmentation.max_updates must be a positive integer, got {self.max_updates!r}")
        for key in ("pressure_rtol", "gap_rtol"):
            if not (getattr(self, key) > 0):
                raise ConfigError(f"augmentation.{key} must be > 0, got {getattr(self, key)!r}")
        for key in ("penalty_growth", "max_penalty_scale"):
            if not (getattr(self, key) >= 1.0):
                raise ConfigError(f"augmentation.{key} must be >= 1, got {getattr(self, key)!r}")
        if not (0.0 <= self.inexact < 1.0):
            raise ConfigError(f"augmentation.inexact must lie in [0, 1), got {self.inexact!r}")
        if self.intermediate not in ("update", "converge"):
            raise ConfigError(f"augmentation.intermediate must be 'update' or 'converge', got {self.intermediate!r}")


@dataclass(frozen=True, eq=False)
class State:
    """A converged equilibrium (returned, never stored on the model).

    Attributes
    ----------
    u : (n_dofs,) stacked displacements
    t : load factor reached (1.0 when the whole load was applied)
    rho : (n_cells,) stiffness factors used
    mass : (n_cells,) material share per cell scaling the volume loads, or None (all full)
    logs : NewtonLog of every Newton solve (failed ones included)
    reactions : (n_dofs,) residual = reaction forces on constrained dofs, ~0 elsewhere
    multipliers : contact pressures per interface (over its nonmortar nodes)
    contact : per-interface InterfaceResult at the converged state (gaps, pressures, ...)
    alm_updates : number of multiplier updates over all load steps
    eps : contact penalty per interface in use at the end (ALM may have grown it)
    evaluation : the Evaluation (residual, tangent, contact results) at ``u`` with the multipliers
        of the last Newton solve: the converged tangent that the adjoint reuses
    """

    u: np.ndarray
    t: float
    rho: np.ndarray
    logs: tuple
    reactions: np.ndarray = field(repr=False, default=None)
    multipliers: tuple = ()
    contact: tuple = ()
    alm_updates: int = 0
    eps: tuple = ()
    evaluation: object = field(repr=False, default=None)
    mass: np.ndarray | None = field(repr=False, default=None)

    @property
    def newton_iterations(self) -> int:
        return int(sum(lg.iterations for lg in self.logs if lg.converged))

    @property
    def seconds(self) -> dict:
        out: dict = {}
        for lg in self.logs:
            for k, v in lg.seconds.items():
                out[k] = out.get(k, 0.0) + v
        return out


@dataclass(frozen=True, eq=False)
class Problem:
    """A model's bulk and contact discretizations, built once and reused across solves."""

    disc: Discretization
    contact: object  # ContactDiscretization, or None without interfaces

    @property
    def has_contact(self) -> bool:
        return self.contact is not None and not self.contact.empty

    @classmethod
    def build(cls, model: Model | Discretization | "Problem") -> "Problem":
        if isinstance(model, Problem):
            return model
        disc = model if isinstance(model, Discretization) else discretize(model)
        if not disc.model.interfaces:
            return cls(disc=disc, contact=None)
        from contopt.contact.system import discretize_contact  # contact costs imports only when used

        return cls(disc=disc, contact=discretize_contact(disc.model, disc))

    def evaluate(self, u, t, rho, p, tangent=True, eps=None, touch=0.0, mass=None) -> Evaluation:
        """Bulk + contact residual, potential and tangent at load factor t with multipliers p.

        Where some node penetrates deeper than :data:`DEEP_PENETRATION` facet
        sizes (a transient of the first iterations after contact starts, never
        an equilibrium of a sensible eps), the evaluation also offers the tangent
        without the second derivatives of the mortar integrals: weighted by the
        spurious pressures of such a state they are large and indefinite. On
        the fine die-slab with a die exactly as wide as the slab the exact step
        then needed line-search factors of 1/16..1/256 and the first load step
        failed in 25 iterations; with the modified tangent it converged in 10,
        quadratically once shallow.

        ``mass``: per-cell scaling of the volume loads (see :class:`Discretization`).

        ``touch`` (a length): contact nodes closer than this count as closed in
        the tangent (the residual is unchanged); the solver passes the size of
        a load step's prescribed increment to the step's first evaluation.
        """
        ev = self.disc.evaluate(u, t, rho, tangent, mass=mass)
        if not self.has_contact:
            return ev
        ec = self.contact.evaluate(u, p, tangent, eps, touch)
        ev.timings.contact += ec.seconds
        K = K_free = modified = None
        if tangent:
            free = self.disc.free
            K = ev.K + ec.K
            K_free = (ev.K_free + ec.K[free][:, free]).tocsr()
            if self.contact.penetration(ec.results) > DEEP_PENETRATION:
                def modified():
                    return (ev.K_free + ec.K_normal[free][:, free]).tocsr()

        return Evaluation(r=ev.r + ec.r, K=K, K_free=K_free, timings=ev.timings, energy=ev.energy + ec.energy,
                          contact=ec.results, K_free_modified=modified)


def solve_static(model: Model | Discretization | Problem, rho=None, newton: NewtonOptions | None = None,
                 linear: LinearSolverOptions | None = None, augmentation: AugmentationOptions | None = None,
                 u0: np.ndarray | None = None, multipliers0: tuple | None = None, on_step=None,
                 eps0: tuple | None = None, mass=None) -> State:
    """Solve for equilibrium at load factor 1 (in load steps from 0).

    Parameters
    ----------
    model : a Model, its Discretization or a Problem (to reuse precomputation across solves)
    rho : (n_cells,) stiffness factor per cell over all bodies (default ones)
    mass : (n_cells,) material share per cell that scales body forces and accelerations (default:
        None, the loads as given); a design problem passes the volume fraction nu
    u0, multipliers0 : start from this displacement / these contact pressures (e.g. the last design's)
    eps0 : start each load step's augmentations from these penalties (one per interface; e.g. a
        previous state's ``eps``, which the augmentations grew): near a converged state the
        multipliers then need a few updates instead of a dozen. Growth stays capped relative to
        the interfaces' own eps.
    on_step : called with a :class:`State` after every converged load step (output, progress)

    Raises :class:`contopt.errors.ConvergenceError` (with logs and the last
    converged state) when a load step cannot converge.
    """
    prob = Problem.build(model)
    disc = prob.disc
    rho = disc.check_rho(rho)
    mass = disc.check_mass(mass)
    newton = newton or NewtonOptions()
    linear = linear or LinearSolverOptions()
    augmentation = augmentation or AugmentationOptions()
    f_norm = float(np.linalg.norm(disc.f_ext(mass)[disc.free]))
    p0 = (tuple(multipliers0) if multipliers0 is not None
          else prob.contact.zero_multipliers() if prob.has_contact else ())
    counter = {"alm": 0}

    eps_own = tuple(b.eps for b in prob.contact.blocks) if prob.has_contact else ()
    if eps0 is not None and len(tuple(eps0)) != len(eps_own):
        raise ConfigError(f"eps0 needs one penalty per contact interface ({len(eps_own)}), got {eps0!r}")
    eps_start = tuple(float(e) for e in eps0) if eps0 is not None else eps_own

    all_penalty = prob.has_contact and all(b.interface.enforcement == "penalty" for b in prob.contact.blocks)

    def good_enough(p):
        """Stop Newton early when a multiplier update will follow and move the state much more."""
        if not prob.has_contact or all_penalty or augmentation.inexact == 0.0:
            return None

        def test(ev, r_norm, r_ref):
            dp, pen = _augmentation_measures(prob.contact, ev.contact, p, tuple(res.lam for res in ev.contact))
            if dp <= augmentation.pressure_rtol and pen <= augmentation.gap_rtol:
                return False  # this may be the last augmentation: full Newton accuracy
            return r_norm <= augmentation.inexact * dp * r_ref

        return test

    in_contact = {"any": False}  # did the last converged solve carry contact pressure?

    def step(u, t, dt, p):
        logs, eps, eps_prev, last_error, grow = [], eps_start, eps_start, None, True
        # contact-aware predictor while no node carries pressure yet: the step's first tangent
        # treats as closed every contact node that the prescribed increment could close, so the
        # predictor pushes the touched body instead of driving the pusher through it (fine
        # die-slab, first step: residual after the predictor 0.079 instead of 4.5, 8 iterations
        # instead of a failure). Once contact is established the plain predictor is better.
        reach = 0.0
        if not in_contact["any"]:
            reach = float(np.abs(disc.prescribed(t) - u[disc.constrained]).max(initial=0.0))
        first = [reach]
        for update in range(augmentation.max_updates + 1):
            def evaluate(v, tangent, p=p, eps=eps):
                touch, first[0] = first[0], 0.0
                return prob.evaluate(v, t, rho, p, tangent, eps, touch, mass=mass)

            try:
                u, lg, ev = newton_step(evaluate, u, disc.free, disc.constrained, disc.prescribed(t), t, dt,
                                        t * f_norm, newton, linear, good_enough=good_enough(p))
            except StepFailure as fail:
                if eps != eps_prev:
                    # a grown penalty can make the active set chatter: go back to the last eps that
                    # converged (from the same converged u) and stop growing it in this step
                    log.info("  Newton failed after the penalty grew; back to eps = %s", list(eps_prev))
                    logs.append(_with_extra(fail.log, alm_update=update, eps=list(eps)))
                    eps, grow = eps_prev, False
                    continue
                fail.log = _with_extra(fail.log, alm_update=update)
                raise
            if not prob.has_contact:
                return StepResult(t=t, u=u, logs=(lg,), evaluation=ev, state=p)
            in_contact["any"] = any(res.n_active > 0 for res in ev.contact)
            p_new = tuple(res.lam for res in ev.contact)
            dp, pen = _augmentation_measures(prob.contact, ev.contact, p, p_new)
            logs.append(_with_extra(lg, alm_update=update, pressure_change=dp, penetration=pen, eps=list(eps),
                                    active=[res.n_active for res in ev.contact],
                                    contact_area=[float(res.a[res.lam > 0].sum()) for res in ev.contact]))
            log.info("  contact: %s active nodes, area %s, pressure change %.2e, penetration %.2e h, eps %s",
                     logs[-1].extra["active"], ["%.4g" % a for a in logs[-1].extra["contact_area"]], dp, pen,
                     ["%.3g" % e for e in eps])
            converged = dp <= augmentation.pressure_rtol and pen <= augmentation.gap_rtol
            final = t >= 1.0 or augmentation.intermediate == "converge"
            if all_penalty or converged or not final:
                if not final and not all_penalty:  # carry the improved multipliers to the next step
                    counter["alm"] += 1
                    p = _update(prob.contact, p, p_new)
                return StepResult(t=t, u=u, logs=tuple(logs), evaluation=ev, state=p)
            counter["alm"] += 1
            p = _update(prob.contact, p, p_new)
            eps_prev = eps
            # distance to convergence in units of the tolerances: grow eps when it fell less than 4x
            error = max(dp / augmentation.pressure_rtol, pen / augmentation.gap_rtol)
            if grow and last_error is not None and error > 0.25 * last_error:
                eps = tuple(min(e * augmentation.penalty_growth, e0 * augmentation.max_penalty_scale)
                            for e, e0 in zip(eps, eps_own))
            last_error = error
        if pen <= augmentation.gap_rtol and dp <= 100.0 * augmentation.pressure_rtol:
            # the constraint holds; the pressures only wander at round-off level (large eps)
            log.warning("augmented Lagrangian stagnated at a pressure change of %.2e (target %.2e) with the "
                        "gap closed; accepting the step", dp, augmentation.pressure_rtol)
            return StepResult(t=t, u=u, logs=tuple(logs), evaluation=ev, state=p)
        raise StepFailure(f"augmented Lagrangian did not converge in {augmentation.max_updates} updates "
                          f"(pressure change {dp:.2e}, penetration {pen:.2e} of the facet size)", logs[-1])

    def step_callback(res: StepResult):
        if on_step is not None:
            on_step(_state(res, rho, res.logs, counter["alm"], eps_start, mass))

    logs, last = solve_load_steps(step, disc.n_dofs, disc.constrained, disc.prescribed, newton,
                                  u0=u0, state0=p0, on_step=step_callback)
    return _state(last, rho, tuple(logs), counter["alm"], eps_start, mass)


def _state(res: StepResult, rho, logs, alm_updates, eps0=(), mass=None) -> State:
    ev = res.evaluation
    contact = tuple(ev.contact) if ev is not None and ev.contact is not None else ()
    eps = tuple(res.logs[-1].extra.get("eps", eps0)) if res.logs else tuple(eps0)
    return State(u=res.u, t=res.t, rho=rho, logs=tuple(logs), reactions=None if ev is None else ev.r,
                 multipliers=tuple(res.state or ()), contact=contact, alm_updates=alm_updates, eps=eps,
                 evaluation=ev, mass=mass)


def _augmentation_measures(contact, results, p, p_new) -> tuple[float, float]:
    """(relative multiplier change, largest penetration / facet size) over all ALM interfaces."""
    dp, scale = 0.0, 0.0
    for block, pi, pn in zip(contact.blocks, p, p_new):
        if block.interface.enforcement == "alm":
            dp = max(dp, float(np.abs(pn - pi).max(initial=0.0)))
            scale = max(scale, float(np.abs(pn).max(initial=0.0)))
    return (dp / scale if scale > 0 else 0.0), contact.penetration(results, enforcement=("alm",))


def _update(contact, p, p_new) -> tuple:
    """Uzawa update on the ALM interfaces (penalty interfaces keep p = 0)."""
    return tuple(pn if b.interface.enforcement == "alm" else pi for b, pi, pn in zip(contact.blocks, p, p_new))


def _with_extra(lg, **extra):
    from dataclasses import replace

    return replace(lg, extra={**lg.extra, **extra})
