"""Aggregated von Mises stress with the qp-relaxation (Bruggi 2008; Le et al. 2010).

Per cell ``e`` of the chosen bodies:

* ``sigma_e`` (3, 3): the cell-average Cauchy stress of the *solid* material,
  ``sum_q wdet_q sigma_q / V_e`` with ``sigma_q = P(Fbar_q) Fbar_q^T / det Fbar_q`` at the 2x2x2
  Gauss points, ``P = d psi / dF`` from the same energy and the same F-bar gradient the analysis
  uses (:func:`contopt.fem.element.cauchy_stress`); the average is what the VTU output's
  ``von_mises`` shows (there scaled by the stiffness factor);
* ``s_e = sqrt(3/2 dev(sigma_e) : dev(sigma_e))``, its von Mises stress;
* the relaxed stress ``r_e = rho_e^q s_e`` with ``rho_e`` the stiffness factor the response sees
  (SIMP: ``rho = (1 - nu0) nu^p + nu0``). ``q = 0`` is the solid stress (whose constraint has
  singular optima: a cell cannot leave the design continuously); ``q = 1`` is the stress of the
  ersatz material itself (too lax: grey cells look unstressed). In between is the qp-relaxation:
  with the SIMP power p, ``q = q_nu / p`` gives the ``nu^q_nu`` relaxation of Le et al. (their
  ``q_nu = 1/2``, p = 3: q = 1/6) and ``q = 1 - q_B / p`` Bruggi's ``q_B``.

Aggregated (``aggregate``) by a volume-weighted p-norm (``"pnorm"``, the default; ``P`` below,
the option ``p``)::

    stress = ( sum_e V_e r_e^P / sum_e V_e )^(1/P)

so that a uniform relaxed stress returns itself exactly; it is a lower bound of ``max_e r_e``
that approaches it as P grows (a stress limit on it is a limit on the peaks, loose by a factor
that shrinks with P; a peak in a cell of volume share w is underestimated at most by w^(1/P)).
Or by the volume-weighted, lower-bound Kreisselmeier-Steinhauser function (``"ks"``; ``s`` the
option ``sharpness``, in 1/stress)::

    stress = (1/s) log( sum_e V_e exp(s r_e) / sum_e V_e )

the smooth maximum of :mod:`contopt.responses.path` over the cells: the weights ``V_e / V`` sum to
one, so it also returns a uniform stress exactly and lies below the peak, within ``log(V / V_e) / s``
of it for a peak in cell e (the plain KS ``(1/s) log sum_e exp(s r_e)`` lies above the peak, by up to
``log(n) / s``). It is evaluated shifted by the peak, ``m + (1/s) log(sum_e V_e exp(s (r_e - m)) / V)``
with ``m = max_e r_e`` (no overflow whatever ``s r_e``); the shift is a constant, so the partials are
``sum_e a_e dr_e`` with ``a_e = V_e exp(s (r_e - stress)) / V`` (summing to one). A cell without
stress has no derivative of ``s_e`` (a cone); there its partials are taken as 0.
The peaks under a contact tool are cells like any other: they enter through ``u``.

``region`` (optional) narrows the cells to those whose reference centre it holds: a callable
``(k, 3) centres -> (k,) bool``, such as :class:`contopt.design.space.BoxRegion` (problem files:
``region = { lower = [...], upper = [...] }`` or a list of boxes, as the design's ``solid`` and
``void``): a stress limit on a fillet or under a tool, not on the whole body. The sums above then run
over the region's cells only.

Partial derivatives from JAX through the same cell kernel (exact, F-bar included).
"""

from __future__ import annotations

from functools import cache

import jax.numpy as jnp
import numpy as np

from contopt.errors import ConfigError
from contopt.fem.element import cauchy_stress
from contopt.responses.base import Fields, Partials, Response, as_fields
from contopt.responses.catalog import AGGREGATES
from contopt.responses.cells import add_partials, bulk_integral, cell_terms


def _number(key: str, value, check, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value) or not check(value):
        raise ConfigError(f"Stress.{key} must be {what}, got {value!r}")
    return float(value)


def von_mises_power(sigma, power: float):
    """``s^power`` of the von Mises stress ``s`` of ``sigma`` (3, 3), written as ``(3/2 s:s)^(power/2)``
    so that its derivative is finite at zero stress (power >= 2)."""
    dev = sigma - jnp.trace(sigma) * jnp.eye(3) / 3.0
    return (1.5 * jnp.sum(dev * dev)) ** (0.5 * power)


def von_mises(sigma):
    """The von Mises stress of ``sigma`` (3, 3), with the derivative 0 at zero stress (where it has
    none: a cone) instead of the square root's NaN."""
    square = von_mises_power(sigma, 2.0)
    stressed = square > 0.0
    return jnp.where(stressed, jnp.sqrt(jnp.where(stressed, square, 1.0)), 0.0)


def _cell_average(u, grad, wdet, params, energy, use_fbar: bool):
    """(3, 3) the cell's volume-average Cauchy stress, and its volume."""
    sigma_q = cauchy_stress(u, grad, wdet, params, energy, use_fbar)  # (q, 3, 3)
    volume = jnp.sum(wdet)
    return jnp.einsum("q,qij->ij", wdet / volume, sigma_q), volume


@cache
def stress_integrand(energy, use_fbar: bool, p: float, q: float):
    """Cell integrand ``V_e (rho_e^q s_e)^p`` (one object per material and options, so jit caches it)."""

    def integrand(u, X, grad, wdet, rho, N, params):
        sigma, volume = _cell_average(u, grad, wdet, params, energy, use_fbar)
        return volume * rho ** (q * p) * von_mises_power(sigma, p)

    return integrand


@cache
def relaxed_stress(energy, use_fbar: bool, q: float):
    """Cell value ``r_e = rho_e^q s_e``, the relaxed von Mises stress (one object per material and q)."""

    def integrand(u, X, grad, wdet, rho, N, params):
        sigma, _ = _cell_average(u, grad, wdet, params, energy, use_fbar)
        return rho**q * von_mises(sigma)

    return integrand


class Stress(Response):
    """Volume-weighted p-norm or KS function of the relaxed von Mises stress over the bodies (module docstring).

    Parameters
    ----------
    bodies : names of the bodies aggregated over (default: all)
    p : the p-norm's exponent, >= 2 (default 8): larger is closer to the maximum and less smooth
    q : relaxation exponent on the stiffness factor, in [0, 1] (default 0.5)
    region : callable ``(k, 3) reference cell centres -> (k,) bool``, the cells aggregated over
        (e.g. :class:`contopt.design.space.BoxRegion`; default: every cell)
    aggregate : ``"pnorm"`` (default) or ``"ks"``, the lower-bound KS function
    sharpness : the KS function's ``s`` > 0, in 1/stress (with ``aggregate="ks"`` only, and needed there)
    """

    def __init__(
        self,
        bodies=None,
        p: float | None = None,
        q: float = 0.5,
        region=None,
        aggregate: str = "pnorm",
        sharpness: float | None = None,
        name: str = "stress",
    ):
        from contopt.responses.functionals import as_names  # which registers Stress: here, not atop (circular)

        if not isinstance(aggregate, str) or aggregate not in AGGREGATES:
            raise ConfigError(f"Stress.aggregate must be one of {AGGREGATES}, got {aggregate!r}")
        if aggregate == "ks" and p is not None:
            raise ConfigError('Stress.p is the p-norm\'s exponent: with aggregate = "ks" give sharpness instead')
        if aggregate == "pnorm" and sharpness is not None:
            raise ConfigError('Stress.sharpness is the KS function\'s: give it with aggregate = "ks"')
        if aggregate == "ks" and sharpness is None:
            raise ConfigError('Stress.sharpness is needed with aggregate = "ks" (in 1/stress, e.g. 20 / the limit)')
        self.bodies = as_names(bodies)
        self.aggregate = aggregate
        self.p = _number("p", 8.0 if p is None else p, lambda v: v >= 2.0, "a number >= 2 (the p-norm's exponent)")
        self.sharpness = (
            None
            if sharpness is None
            else _number("sharpness", sharpness, lambda v: v > 0.0, "a positive number (1/stress)")
        )
        self.q = _number("q", q, lambda v: 0.0 <= v <= 1.0, "a number in [0, 1] (0: solid stress, 1: ersatz)")
        if region is not None and not callable(region):
            raise ConfigError(f"Stress.region must be a callable on cell centres (e.g. BoxRegion), got {region!r}")
        self.region = region
        self.name = name

    def check(self, system) -> None:
        from contopt.responses.functionals import selected_bodies

        disc = system.disc
        indices = selected_bodies(disc, self.bodies)
        if self.region is not None and not any(self._in_region(disc, i).any() for i in indices):
            names = [disc.model.bodies[i].name for i in indices]
            raise ConfigError(f"{self.name}: its region {self.region!r} holds no cell centre of {names}; widen it")

    def _in_region(self, disc, i: int) -> np.ndarray:
        """(m,) the cells of body ``i`` whose reference centre lies in the region (all without one)."""
        from contopt.design.space import cell_centroids

        mesh = disc.model.bodies[i].mesh
        if self.region is None:
            return np.ones(len(mesh.cells), bool)
        keep = np.asarray(self.region(cell_centroids(mesh)), dtype=bool)
        if keep.shape != (len(mesh.cells),):
            raise ConfigError(f"{self.name}: its region returned shape {keep.shape}, one flag a cell is needed")
        return keep

    def _integrand(self, block):
        return stress_integrand(block.energy, block.fbar, self.p, self.q)

    def total_volume(self, disc) -> float:
        from contopt.responses.functionals import selected_bodies

        return float(
            sum(disc.blocks[i].volume[self._in_region(disc, i)].sum() for i in selected_bodies(disc, self.bodies))
        )

    def _cells_of(self, disc):
        return None if self.region is None else (lambda i: self._in_region(disc, i))

    def evaluate(self, fields: Fields, gradient: bool = True):
        from contopt.responses.functionals import selected_bodies

        fields = as_fields(fields, self.name)
        self.check(fields.system)
        if self.aggregate == "ks":
            return self._ks(fields, gradient)
        disc = fields.disc
        partials = Partials.zeros(fields) if gradient else None
        bodies = selected_bodies(disc, self.bodies)
        total = bulk_integral(fields, bodies, self._integrand, gradient, partials, self._cells_of(disc))
        mean = total / self.total_volume(disc)
        value = mean ** (1.0 / self.p) if mean > 0.0 else 0.0
        if partials is None:
            return value, None
        # d(mean^(1/p))/d(total) = value / (p total); at zero stress everywhere the p-norm has no
        # derivative (a cone): the response is 0 there and its partials are left 0
        weight = value / (self.p * total) if total > 0.0 else 0.0
        return value, Partials(u=weight * partials.u, lam=partials.lam, rho=weight * partials.rho)

    def _ks(self, fields: Fields, gradient: bool):
        """The KS aggregate (module docstring): ``m + (1/s) log(sum_e V_e exp(s (r_e - m)) / V)``."""
        from contopt.responses.functionals import selected_bodies

        disc = fields.disc
        s = self.sharpness
        assert s is not None  # checked at construction with aggregate = "ks"
        q = self.q
        terms = list(
            cell_terms(
                fields,
                selected_bodies(disc, self.bodies),
                lambda b: relaxed_stress(b.energy, b.fbar, q),
                gradient,
                self._cells_of(disc),
            )
        )
        # the shift m: the peak over every rank's cells (the same number on each, so the sums agree)
        peaks = np.full(disc.comm.size, 0.0)
        peaks[disc.comm.rank] = max((float(t.value.max()) for t in terms), default=0.0)
        m = float(disc.comm.sum(peaks).max())
        # (k,) V_e exp(s (r_e - m)) of each body's cells: each in (0, V_e], one of them V_e
        shares = [disc.blocks[t.body].volume[t.cells - disc.blocks[t.body].cell_offset] for t in terms]
        weights = [v * np.exp(s * (t.value - m)) for v, t in zip(shares, terms)]
        total = float(disc.comm.sum(sum(float(w.sum()) for w in weights)))
        value = m + np.log(total / self.total_volume(disc)) / s
        if not gradient:
            return value, None
        d_u, d_rho = np.zeros(disc.n_dofs), np.zeros(disc.n_cells)
        for w, t in zip(weights, terms):
            add_partials(fields, t, w / total, d_u, d_rho)  # a_e = V_e exp(s (r_e - value)) / V
        zero = Partials.zeros(fields)
        return value, Partials(u=disc.comm.sum(d_u), lam=zero.lam, rho=disc.comm.sum(d_rho))

    def per_cell(self, fields: Fields) -> np.ndarray:
        """(n_cells,) the relaxed von Mises stress ``rho^q s_e`` of each cell (0 outside the bodies)."""
        from contopt.responses.functionals import selected_bodies

        fields = as_fields(fields, self.name)
        disc = fields.disc
        out = np.zeros(disc.n_cells)
        for i in selected_bodies(disc, self.bodies):
            sl = disc.cell_slice(i)
            s = disc.cauchy_stress(fields.u, i, np.ones(disc.n_cells))
            dev = s - np.trace(s, axis1=-2, axis2=-1)[:, None, None] * np.eye(3) / 3.0
            out[sl] = fields.rho[sl] ** self.q * np.sqrt(1.5 * np.sum(dev * dev, axis=(-2, -1)))
            out[sl] *= self._in_region(disc, i)
        return out

    def __repr__(self) -> str:
        region = "" if self.region is None else f", region={self.region!r}"
        how = f"sharpness={self.sharpness:g}" if self.aggregate == "ks" else f"p={self.p:g}"
        return f"Stress({self.name!r}, {how}, q={self.q:g}{region})"
