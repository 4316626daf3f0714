"""The design of a whole model: design variables x -> volume fraction nu -> stiffness factor rho.

Per designed body (paper section 6)::

    phi = G x_b                      cone filter (density) or B-spline (level set), at cell centroids
    phi~ = phi v (s_1 v s_2 ...)     R-function union with solid skins (eq. 46), if any
    nu = 1/2 + 1/2 tanh(eta phi~)    eq. 35; cells fixed solid -> 1, fixed void -> 0
    rho = (1 - nu0) nu^p + nu0       eq. 36; bodies that are not designed keep nu = rho = 1

``DesignSpace.forward`` evaluates the chain, ``DesignSpace.vjp`` pulls a
gradient with respect to ``rho`` (and ``nu``) back to ``x``.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp

from contopt.design.bspline import BSplineGrid
from contopt.design.filter import cone_filter
from contopt.design.maps import EtaContinuation, Heaviside, Robust, Simp, r_union, r_union_partials
from contopt.design.symmetry import AXES, CyclicSymmetry
from contopt.errors import ConfigError
from contopt.io.surface import TriangleSurface
from contopt.mesh.voxel import inside_surface

if TYPE_CHECKING:  # the discretization's module loads JAX, which a problem file's description does not need
    from contopt.assembly.system import Discretization

log = logging.getLogger(__name__)

#: which side of its radius a skin is solid (RadialSkin.side)
SKIN_SIDES = ("inside", "outside")
#: a point whose symmetry image moves less than this (relative to the body size) lies in the fundamental region
FUNDAMENTAL_TOL = 1e-9


@dataclass(frozen=True)
class Density:
    """Density method: one design variable per cell, cone filter of radius ``radius`` (eq. 33)."""

    radius: float

    def __post_init__(self):
        if not isinstance(self.radius, (int, float)) or not np.isfinite(self.radius) or self.radius <= 0:
            raise ConfigError(f"density.radius must be a number > 0, got {self.radius!r}")


@dataclass(frozen=True)
class RadialSkin:
    """Level set of a solid skin by radius about an axis (eq. 45), for the R-function union.

    radius : the skin's radius about the axis
    side : "inside": ``m (radius - r)`` (solid for r < radius); "outside": ``m (r - radius)``
        (solid for r > radius)
    slope : the level set's slope ``m`` (how sharp the skin's edge is)
    axis : "x", "y" or "z"; center : a point on the axis
    """

    radius: float
    side: str = "inside"
    slope: float = 5.0
    axis: str = "z"
    center: tuple = (0.0, 0.0, 0.0)

    def __post_init__(self):
        if self.side not in SKIN_SIDES:
            raise ConfigError(f"skin.side must be 'inside' or 'outside', got {self.side!r}")
        if self.axis not in AXES:
            raise ConfigError(f"skin.axis must be one of {sorted(AXES)}, got {self.axis!r}")
        if not self.radius > 0 or not self.slope > 0:
            raise ConfigError(f"skin.radius and skin.slope must be > 0, got {self.radius!r}, {self.slope!r}")

    def __call__(self, X: np.ndarray) -> np.ndarray:
        i, j, _ = AXES[self.axis]
        rel = np.asarray(X) - np.asarray(self.center)
        r = np.hypot(rel[:, i], rel[:, j])
        return self.slope * ((self.radius - r) if self.side == "inside" else (r - self.radius))


@dataclass(frozen=True)
class BoxRegion:
    """Cells whose centroid lies in the axis-aligned box ``lower <= X <= upper`` (a fixed region)."""

    lower: tuple
    upper: tuple

    def __call__(self, X: np.ndarray) -> np.ndarray:
        return np.all((X >= np.asarray(self.lower)) & (X <= np.asarray(self.upper)), axis=1)


@dataclass(frozen=True, eq=False)
class SurfaceRegion:
    """Cells whose centroid lies inside a closed surface (a fixed region given as a shape: a boss, a channel).

    surface : :class:`~contopt.io.surface.TriangleSurface`, closed (:func:`~contopt.mesh.voxel.read_envelope`
        reads and checks one); name : what messages call it (its file)
    """

    surface: TriangleSurface
    name: str = "surface"

    def __call__(self, X: np.ndarray) -> np.ndarray:
        """(k, 3) centroids -> (k,) bool (ray parity, :func:`~contopt.mesh.voxel.inside_surface`)."""
        return inside_surface(self.surface, X)

    def __repr__(self) -> str:
        return f"SurfaceRegion({self.name!r})"


Region = Callable[[np.ndarray], np.ndarray] | np.ndarray | list | None


@dataclass(frozen=True, eq=False)
class DesignedBody:
    """How one body is designed.

    body : the body's name in the model
    parameterization : :class:`Density` or :class:`contopt.design.bspline.BSplineGrid`
    volume_fraction : nu_max of this body's volume constraint (eq. 44) and the
        initial grey level; None: no volume constraint, start at nu = 0.5
    symmetry : :class:`CyclicSymmetry` (evaluation points are mapped into its fundamental region)
    skins : level-set callables ``(k, 3) centroids -> (k,)`` united with phi by R-functions
    solid, void : cells fixed to nu = 1 / nu = 0: a callable on the (k, 3) centroids
        returning a bool mask, a bool mask, or body-local cell indices
    skin_eps : the R-function's epsilon_phi
    envelope : the closed :class:`~contopt.io.surface.TriangleSurface` the body's voxels were made
        from (:func:`~contopt.mesh.voxel.mesh_envelope`), or None: the design's exported surface
        (:mod:`contopt.design.surface`) is cut to it, not only to the voxels' staircase
    """

    body: str
    parameterization: Density | BSplineGrid
    volume_fraction: float | None = None
    symmetry: CyclicSymmetry | None = None
    skins: tuple = ()
    solid: Region = None
    void: Region = None
    skin_eps: float = 1e-4
    envelope: TriangleSurface | None = None

    def __post_init__(self):
        if not isinstance(self.parameterization, (Density, BSplineGrid)):
            raise ConfigError(
                f"design of body {self.body!r}: parameterization must be Density(radius) or "
                f"BSplineGrid(patches), got {type(self.parameterization).__name__}"
            )
        vf = self.volume_fraction
        if vf is not None and not (isinstance(vf, (int, float)) and 0.0 < vf < 1.0):
            raise ConfigError(f"design of body {self.body!r}: volume_fraction must lie in (0, 1), got {vf!r}")
        if self.symmetry is not None and not isinstance(self.symmetry, CyclicSymmetry):
            raise ConfigError(f"design of body {self.body!r}: symmetry must be CyclicSymmetry(...)")
        object.__setattr__(self, "skins", tuple(self.skins))
        for s in self.skins:
            if not callable(s):
                raise ConfigError(f"design of body {self.body!r}: skins must be callables X -> level set")
        if not self.skin_eps > 0:
            raise ConfigError(f"design of body {self.body!r}: skin_eps must be > 0, got {self.skin_eps!r}")
        if self.envelope is not None and not isinstance(self.envelope, TriangleSurface):
            raise ConfigError(
                f"design of body {self.body!r}: envelope must be a closed TriangleSurface "
                f"(contopt.mesh.voxel.read_envelope), got {type(self.envelope).__name__}"
            )

    @property
    def initial_fraction(self) -> float:
        return 0.5 if self.volume_fraction is None else float(self.volume_fraction)


@dataclass(frozen=True, eq=False)
class Design:
    """The designed bodies of a model and the maps shared by all of them.

    robust : :class:`~contopt.design.maps.Robust` for the robust formulation (density designs
        only): the optimization analyses the eroded, intermediate and dilated designs
    eta_continuation : :class:`~contopt.design.maps.EtaContinuation`: the optimization raises the
        Heaviside's sharpness from its ``start`` to ``heaviside.eta`` within the run (None: eta throughout)
    """

    bodies: tuple
    heaviside: Heaviside = field(default_factory=Heaviside)
    simp: Simp = field(default_factory=Simp)
    robust: Robust | None = None
    eta_continuation: EtaContinuation | None = None

    def __post_init__(self):
        bodies = (self.bodies,) if isinstance(self.bodies, DesignedBody) else tuple(self.bodies)
        if not bodies or not all(isinstance(b, DesignedBody) for b in bodies):
            raise ConfigError("a design needs at least one DesignedBody(...)")
        names = [b.body for b in bodies]
        if len(set(names)) != len(names):
            raise ConfigError(f"each body can be designed once, got {names}")
        object.__setattr__(self, "bodies", bodies)
        if self.robust is not None:
            if not isinstance(self.robust, Robust):
                raise ConfigError(f"Design.robust must be Robust(delta) or None, got {type(self.robust).__name__}")
            level_sets = [b.body for b in bodies if not isinstance(b.parameterization, Density)]
            if level_sets:
                raise ConfigError(
                    f"robust applies to density designs only; body {level_sets[0]!r} is a B-spline level set: "
                    "design it with density = {radius = ...} or drop robust"
                )
        if self.eta_continuation is not None:
            if not isinstance(self.eta_continuation, EtaContinuation):
                raise ConfigError(
                    "Design.eta_continuation must be EtaContinuation(start, factor, every) or None, got "
                    f"{type(self.eta_continuation).__name__}"
                )
            self.eta_continuation.etas(self.heaviside.eta)  # start below eta, else one line

    def at_eta(self, eta: float) -> Design:
        """This design at the Heaviside sharpness ``eta`` (one stage of its continuation), without the continuation."""
        return replace(self, heaviside=replace(self.heaviside, eta=eta), eta_continuation=None)

    def realization(self, name: str) -> Design:
        """The design of one robust realization ("eroded", "intermediate", "dilated"): the
        Heaviside's threshold shifted by ``robust.threshold(name)``, without ``robust``."""
        if self.robust is None:
            raise ConfigError("this design has no robust formulation (Design.robust is None)")
        h = Heaviside(self.heaviside.eta, self.heaviside.threshold + self.robust.threshold(name))
        return Design(bodies=self.bodies, heaviside=h, simp=self.simp)

    def build(self, disc: Discretization) -> DesignSpace:
        """Precompute G, skins and fixed regions on the model's Discretization (``system.disc``)."""
        from contopt.assembly.system import Discretization  # JAX: kept out of reading a problem file

        if not isinstance(disc, Discretization):
            raise ConfigError(
                f"Design.build needs the model's Discretization (discretize(model), or system.disc), "
                f"got {type(disc).__name__}"
            )
        parts, offset = [], 0
        for spec in self.bodies:
            part = _build_part(disc, spec, offset)
            parts.append(part)
            offset += part.n
        return DesignSpace(design=self, n_cells=disc.n_cells, parts=tuple(parts), n=offset)


@dataclass(frozen=True, eq=False)
class Part:
    """One designed body, precomputed.

    cells : slice of the model's cells; x : slice of the design vector
    G : (k, n_b) CSR from design variables to cell level sets
    skin : (k,) united skin level set, or None
    fixed : (k,) -1 free, 0 fixed void, 1 fixed solid
    volumes : (k,) cell volumes; sites : (n_b, 3) where the design variables sit
    """

    spec: DesignedBody
    cells: slice
    x: slice
    G: sp.csr_matrix
    skin: np.ndarray | None
    fixed: np.ndarray
    volumes: np.ndarray
    centroids: np.ndarray
    sites: np.ndarray

    @property
    def n(self) -> int:
        return self.G.shape[1]

    @property
    def nnz(self) -> int:
        return int(self.G.nnz)


def cell_centroids(mesh) -> np.ndarray:
    """(m, 3) cell centres: of hex8 the isoparametric centre (mean of the 8 nodes), of tet4 / tet10
    the mean of the 4 corners (the centroid of a straight-sided tet)."""
    corners = mesh.cells if mesh.cells.shape[1] == 8 else mesh.cells[:, :4]
    return mesh.points[corners].mean(axis=1)


def _region_mask(region: Region, X: np.ndarray, what: str, body: str) -> np.ndarray:
    k = len(X)
    if region is None:
        return np.zeros(k, bool)
    if callable(region):
        mask = np.asarray(region(X))
        if mask.shape != (k,):
            raise ConfigError(
                f"design of body {body!r}: the {what} region returned shape {mask.shape}, expected ({k},) booleans"
            )
        return mask.astype(bool)
    arr = np.asarray(region)
    if arr.dtype == bool:
        if arr.shape != (k,):
            raise ConfigError(f"design of body {body!r}: the {what} mask has shape {arr.shape}, expected ({k},)")
        return arr
    if arr.size and (arr.min() < 0 or arr.max() >= k or not np.issubdtype(arr.dtype, np.integer)):
        raise ConfigError(f"design of body {body!r}: {what} cell indices must be integers in [0, {k})")
    mask = np.zeros(k, bool)
    mask[arr.astype(np.int64)] = True
    return mask


def _fixed(spec: DesignedBody, X: np.ndarray) -> np.ndarray:
    """(k,) int8 per cell: -1 free, 0 fixed void, 1 fixed solid (by centroid X (k, 3))."""
    solid = _region_mask(spec.solid, X, "solid", spec.body)
    void = _region_mask(spec.void, X, "void", spec.body)
    if np.any(solid & void):
        raise ConfigError(
            f"design of body {spec.body!r}: {int(np.sum(solid & void))} cell(s) are fixed both solid and void"
        )
    fixed = np.full(len(X), -1, np.int8)
    fixed[void], fixed[solid] = 0, 1
    return fixed


def _without_fixed(G: sp.csr_matrix, fixed: np.ndarray, home: np.ndarray) -> sp.csr_matrix:
    """The cone filter (k, n_b) averaging free cells' variables only.

    A fixed cell's own value is set after the projection, so its variable would otherwise be a ghost: free
    to move (it changes nothing where it sits) and seen by its free neighbours, which would let a keep-out
    region's variable build material next to it, or a keep-in's stiffen its surroundings. Its column is
    dropped from the free cells' rows (which are normalized again, so a uniform design stays uniform), and
    its variable then moves nothing at all (a zero gradient). A row left empty (a cell whose neighbours
    within the radius are all fixed: a fixed cell, or under a symmetry a free cell whose image is) keeps
    its plain filter.
    """
    free_site = (fixed[home] < 0).astype(np.float64)
    kept = (G @ sp.diags(free_site)).tocsr()
    kept.eliminate_zeros()
    sums = np.asarray(kept.sum(axis=1)).ravel()
    use = (sums > 0) & (fixed < 0)
    scale = np.where(use, 1.0 / np.where(use, sums, 1.0), 0.0)
    out = sp.diags(scale) @ kept + sp.diags((~use).astype(np.float64)) @ G
    out = out.tocsr()
    out.eliminate_zeros()
    out.sort_indices()
    return out


def _build_part(disc, spec: DesignedBody, offset: int) -> Part:
    i = disc.model.body_index(spec.body)
    if disc.model.bodies[i].rigid is not None:
        raise ConfigError(f"design of body {spec.body!r}: the body is a rigid tool; design a deformable body")
    block, mesh = disc.blocks[i], disc.model.bodies[i].mesh
    X = cell_centroids(mesh)
    points = spec.symmetry.map(X) if spec.symmetry is not None else X
    volumes = np.asarray(block.volume, dtype=np.float64)
    fixed = _fixed(spec, X)
    param = spec.parameterization
    if isinstance(param, Density):
        # design variables sit at the centroids of the cells inside the symmetry's fundamental region
        size = float(np.ptp(X, axis=0).max()) or 1.0
        home = np.linalg.norm(points - X, axis=1) <= FUNDAMENTAL_TOL * size
        if not home.any():
            raise ConfigError(
                f"design of body {spec.body!r}: no cell centroid lies in the symmetry's "
                "fundamental region; check symmetry.start and symmetry.center"
            )
        sites = X[home]
        G = _without_fixed(cone_filter(points, sites, volumes[home], param.radius), fixed, home)
    else:
        box = param.box(points)
        G = param.matrix(points, box)
        sites = param.greville(box)
    skin = None
    if spec.skins:
        skin = np.asarray(spec.skins[0](X), dtype=np.float64)
        for s in spec.skins[1:]:
            skin = r_union(skin, np.asarray(s(X), dtype=np.float64), spec.skin_eps)
    cells = slice(block.cell_offset, block.cell_offset + block.n_cells)
    return Part(
        spec=spec,
        cells=cells,
        x=slice(offset, offset + G.shape[1]),
        G=G.tocsr(),
        skin=skin,
        fixed=fixed,
        volumes=volumes,
        centroids=X,
        sites=sites,
    )


@dataclass(frozen=True, eq=False)
class DesignFields:
    """The design chain evaluated at ``x`` (cell arrays cover all the model's cells).

    x : (n,) design variables
    phi : (n_cells,) level set ``G x`` (0 in bodies that are not designed)
    phi_tilde : (n_cells,) after the union with skins
    nu : (n_cells,) volume fraction; rho : (n_cells,) stiffness factor
    """

    x: np.ndarray
    phi: np.ndarray
    phi_tilde: np.ndarray
    nu: np.ndarray
    rho: np.ndarray


@dataclass(frozen=True, eq=False)
class DesignSpace:
    """A :class:`Design` built on a discretization: ``forward``, ``vjp`` and volume fractions."""

    design: Design
    n_cells: int
    parts: tuple
    n: int

    @property
    def lower(self) -> np.ndarray:
        return -np.ones(self.n)

    @property
    def upper(self) -> np.ndarray:
        return np.ones(self.n)

    @property
    def names(self) -> list[str]:
        return [p.spec.body for p in self.parts]

    def initial(self) -> np.ndarray:
        """The all-grey start ``x_i = ln(nu/(1-nu)) / (2 eta)`` with nu each body's volume fraction.

        Where G's rows sum to one (normalized filter, B-spline partition of unity)
        every free cell then starts at exactly nu. A body with solid skins or fixed
        regions would then start above (or below) its volume fraction: its uniform
        level is instead the one at which the body's volume fraction is the target
        (bisection; the start is feasible, as the paper's grey start is).
        """
        x = np.empty(self.n)
        for p in self.parts:
            x[p.x] = self.design.heaviside.inverse(p.spec.initial_fraction)
        for k, p in enumerate(self.parts):
            if p.spec.volume_fraction is not None and (p.skin is not None or (p.fixed >= 0).any()):
                x[p.x] = self._level_for_fraction(x, k, p.spec.volume_fraction)
        return x

    def _level_for_fraction(self, x: np.ndarray, k: int, target: float) -> float:
        """The uniform value of part k's variables giving it volume fraction ``target`` (within the bounds)."""
        p = self.parts[k]
        lo, hi = float(self.lower[p.x].min()), float(self.upper[p.x].max())

        def fraction(level):
            y = x.copy()
            y[p.x] = level
            return self.volume_fractions(self.forward(y))[k]

        if fraction(lo) >= target:
            log.warning(
                "design of body %r: its solid and fixed regions alone exceed the volume fraction %g; "
                "starting from the lower bound",
                p.spec.body,
                target,
            )
            return lo
        if fraction(hi) <= target:
            return hi
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if fraction(mid) < target else (lo, mid)
        return 0.5 * (lo + hi)

    def check_x(self, x) -> np.ndarray:
        x = np.asarray(x, dtype=np.float64)
        if x.shape != (self.n,):
            raise ConfigError(
                f"the design vector needs {self.n} entries ({self.describe_sizes()}), got shape {x.shape}"
            )
        if not np.all(np.isfinite(x)):
            raise ConfigError("the design vector has non-finite entries")
        return x

    def describe_sizes(self) -> str:
        return ", ".join(f"{p.spec.body}: {p.n}" for p in self.parts)

    def forward(self, x) -> DesignFields:
        x = self.check_x(x)
        phi, phit, nu = np.zeros(self.n_cells), np.zeros(self.n_cells), np.ones(self.n_cells)
        for p in self.parts:
            ph = p.G @ x[p.x]
            pt = ph if p.skin is None else r_union(ph, p.skin, p.spec.skin_eps)
            v = self.design.heaviside.forward(pt)
            v[p.fixed >= 0] = p.fixed[p.fixed >= 0]
            phi[p.cells], phit[p.cells], nu[p.cells] = ph, pt, v
        return DesignFields(x=x, phi=phi, phi_tilde=phit, nu=nu, rho=self.design.simp.forward(nu))

    def vjp(self, fields: DesignFields, rho_bar=None, nu_bar=None) -> np.ndarray:
        """``x_bar = (d rho/dx)^T rho_bar + (d nu/dx)^T nu_bar``: (n,)."""
        total = np.zeros(self.n_cells)
        if rho_bar is not None:
            total += self.design.simp.vjp(fields.nu, np.asarray(rho_bar, dtype=np.float64))
        if nu_bar is not None:
            total += np.asarray(nu_bar, dtype=np.float64)
        x_bar = np.zeros(self.n)
        for p in self.parts:
            b = np.where(p.fixed >= 0, 0.0, total[p.cells])
            b = self.design.heaviside.vjp(fields.phi_tilde[p.cells], b)
            if p.skin is not None:
                b = b * r_union_partials(fields.phi[p.cells], p.skin, p.spec.skin_eps)[0]
            x_bar[p.x] = p.G.T @ b
        return x_bar

    def volume_weights(self, part: Part) -> np.ndarray:
        """(n_cells,) weights ``V_e / |Omega_b|`` on the part's cells (zero elsewhere)."""
        w = np.zeros(self.n_cells)
        w[part.cells] = part.volumes / part.volumes.sum()
        return w

    def volume_fractions(self, fields: DesignFields) -> np.ndarray:
        """(n_parts,) ``int nu dV / |Omega_b|`` per designed body (eq. 44, all its cells)."""
        return np.array([self.volume_weights(p) @ fields.nu for p in self.parts])

    def volume_gradient(self, fields: DesignFields, part: Part) -> np.ndarray:
        """(n,) gradient of one designed body's volume fraction with respect to x."""
        return self.vjp(fields, nu_bar=self.volume_weights(part))

    def volume_gradients(self, fields: DesignFields) -> np.ndarray:
        """(n_parts, n) gradients of :meth:`volume_fractions` with respect to x."""
        return np.stack([self.volume_gradient(fields, p) for p in self.parts])

    def full(self) -> DesignFields:
        """The all-solid reference design (nu = rho = 1 everywhere, fixed voids kept void)."""
        nu = np.ones(self.n_cells)
        for p in self.parts:
            nu[p.cells] = np.where(p.fixed == 0, 0.0, 1.0)
        zeros = np.zeros(self.n_cells)
        return DesignFields(x=self.upper, phi=zeros, phi_tilde=zeros, nu=nu, rho=self.design.simp.forward(nu))

    def summary(self) -> list[dict]:
        """Per designed body: parameterization, design variables, nonzeros of G, fixed cells."""
        out = []
        for p in self.parts:
            param = p.spec.parameterization
            kind = (
                ("density", {"radius": param.radius})
                if isinstance(param, Density)
                else (
                    "bspline",
                    {"patches": list(param.patches), "degree": param.degree, "control_points": list(param.shape)},
                )
            )
            out.append(
                {
                    "body": p.spec.body,
                    "parameterization": kind[0],
                    **kind[1],
                    "n_design": p.n,
                    "n_cells": int(p.cells.stop - p.cells.start),
                    "G_nonzeros": p.nnz,
                    "fixed_solid": int(np.sum(p.fixed == 1)),
                    "fixed_void": int(np.sum(p.fixed == 0)),
                    "volume_fraction": p.spec.volume_fraction,
                    **({} if self.design.robust is None else {"robust": {"delta": self.design.robust.delta}}),
                }
            )
        return out
