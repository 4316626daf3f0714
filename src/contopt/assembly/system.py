"""Precomputed discretization of a :class:`Model` and its residual / tangent.

Built once per model (:func:`discretize`): cell geometry of every body (of the
cells this rank evaluates, in a distributed run), the
stacked dof numbering (body ``i`` owns dofs ``dof_offsets[i] + 3*node + c``),
the CSR pattern, Dirichlet dofs, and the unit external load vector. The
design enters as ``rho`` (n_cells_total,), the per-cell stiffness factor
stacked over bodies in model order (``cell_offsets``). Loads per unit
volume (body forces, accelerations) may also depend on the design: they are
multiplied per cell by ``mass`` (n_cells,), the cell's share of material
(the design's volume fraction nu in designed bodies, 1 elsewhere), so that
an inertia load follows the mass that is actually there.

Sign convention: ``r(u) = f_int(u) - t f_ext``; the equilibrium is ``r_free = 0``
and ``r`` on constrained dofs is the reaction force.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial

import numpy as np
import scipy.sparse as sp

from contopt.assembly.kernels import (
    DEFAULT_CHUNK,
    element_energies,
    element_residuals_tangents,
    element_rho_vjps,
    element_stresses,
)
from contopt.assembly.model import BodyForce, Model, Traction
from contopt.assembly.sparse import SparsePattern, SubPattern
from contopt.config import enable_x64
from contopt.errors import ConfigError
from contopt.fem.cells import cell_geometry, face_quadrature
from contopt.fem.hex8 import CellGeometry
from contopt.mesh.core import check_mesh_size
from contopt.parallel import SERIAL, Comm, cell_range, world
from contopt.timing import Stopwatch, timed
from contopt.vectors import dot


@dataclass(frozen=True, eq=False)
class BodyBlock:
    """Per-body precomputed arrays. ``dofs`` (m, 3n) global dofs of each cell (n its nodes); ``own``: the cells
    whose kernels this rank runs (all of them in a serial run, see :mod:`contopt.parallel`);
    ``geometry``: the reference geometry of those cells only (a distributed run keeps no other
    rank's shape gradients, 1.5 kB a cell); ``volume`` (m,): the volume of every cell."""

    name: str
    geometry: CellGeometry
    volume: np.ndarray
    dofs: np.ndarray
    params: np.ndarray
    energy: Callable
    fbar: bool
    node_offset: int
    cell_offset: int
    n_nodes: int
    n_cells: int
    own: slice = field(default_factory=lambda: slice(0, None))  # (slices are unhashable before 3.12)

    def owned(self, *arrays: np.ndarray) -> tuple[np.ndarray, ...]:
        """The rows of per-cell ``arrays`` ((m, ...) each) of the cells this rank evaluates (views)."""
        return tuple(a[self.own] for a in arrays)

    def kernel_inputs(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The dofs (m_own, 3n), shape gradients (m_own, q, n, 3) and weights (m_own, q) of the
        cells this rank evaluates."""
        return self.dofs[self.own], self.geometry.grad, self.geometry.wdet

    @property
    def nodes_per_cell(self) -> int:
        """8 (hex8), 4 (tet4) or 10 (tet10)."""
        return self.dofs.shape[1] // 3

    @property
    def owned_cells(self) -> slice:
        """The owned cells as a slice of the model's cells (of ``rho``, ``mass``)."""
        start = self.cell_offset + (self.own.start or 0)
        stop = self.cell_offset + (self.n_cells if self.own.stop is None else self.own.stop)
        return slice(start, stop)


@dataclass
class Timings:
    """Seconds spent in each phase (accumulated)."""

    kernels: float = 0.0
    scatter: float = 0.0
    factorize: float = 0.0
    solve: float = 0.0
    contact: float = 0.0

    def add(self, other: Timings) -> None:
        for k in ("kernels", "scatter", "factorize", "solve", "contact"):
            setattr(self, k, getattr(self, k) + getattr(other, k))

    def as_dict(self) -> dict:
        return {k: getattr(self, k) for k in ("kernels", "scatter", "factorize", "solve", "contact")}


@dataclass(frozen=True, eq=False)
class ModifiedTangent:
    """A free-free tangent offered beside the exact one: the bulk's ``K_bulk`` (n_free, n_free) plus
    the free-free block of ``K_normal`` (n_dofs, n_dofs; the contact's terms without the second
    derivatives of the mortar integrals; None on a rank other than 0 of a distributed run, which
    holds the bulk's part only). Summed by :meth:`K_free` when Newton takes it, not before."""

    K_bulk: sp.csr_matrix
    K_normal: sp.csr_matrix | None
    free: np.ndarray

    def K_free(self) -> sp.csr_matrix:
        """The modified tangent's free-free block (``K_bulk`` itself where there is no ``K_normal``)."""
        if self.K_normal is None:
            return self.K_bulk
        return (self.K_bulk + self.K_normal[self.free][:, self.free]).tocsr()


@dataclass(frozen=True, eq=False)
class Evaluation:
    """Residual (n_dofs,), total potential energy, and optionally the tangent: its free-free block
    ``K_free`` (n_free, n_free), its free-constrained block ``K_fc`` (n_free, n_constrained) and,
    when asked for (``full=True``), the whole of it.

    The factor needs ``K_free`` and Newton's prescribed increment ``K_fc``; the whole tangent is
    kept (as the terms ``K_terms``, bulk, springs, contact, that sum to it: :attr:`K`,
    :meth:`K_dot`) only for an evaluation made with ``full=True``: on the paper-size sabot its
    values were 145 MB held beside ``K_free`` through every Newton iteration. ``energy`` is the
    total potential ``sum_e W_e - t f_ext . u`` (None where a contribution has no potential); the
    line search uses it.
    ``modified``: None, or the parts of a free-free tangent that Newton uses instead of ``K_free``
    at this state (:class:`ModifiedTangent`: contact far from equilibrium, see
    :meth:`contopt.solve.system.System.evaluate`).
    In a distributed run (:mod:`contopt.parallel`) ``r`` and ``energy`` are the whole model's on
    every rank, but ``K``, ``K_free`` and ``K_fc`` hold this rank's part only (the parts sum to
    the tangent); ``reduce`` sums a vector over the ranks, e.g. ``reduce(K @ v)`` is the tangent
    times ``v``.
    """

    r: np.ndarray
    K_terms: tuple | None
    K_free: sp.csr_matrix | None
    timings: Timings = field(default_factory=Timings)
    energy: float | None = None
    contact: tuple | None = None
    modified: ModifiedTangent | None = None
    reduce: Callable[[np.ndarray], np.ndarray] = SERIAL.sum
    K_fc: sp.csr_matrix | None = None

    @property
    def K(self) -> sp.csr_matrix | None:
        """The full tangent (n_dofs, n_dofs) CSR, summed from ``K_terms`` now (None without a tangent)."""
        if self.K_terms is None:
            self._refuse_partial()
            return None
        total = self.K_terms[0]
        for term in self.K_terms[1:]:
            total = total + term
        return sp.csr_matrix(total)

    def K_dot(self, v: np.ndarray) -> np.ndarray:
        """``K @ v`` (n_dofs,) without forming ``K`` (this rank's part in a distributed run)."""
        if self.K_terms is None:
            self._refuse_partial()
            raise ValueError("this evaluation has no tangent")
        return sum((term @ v for term in self.K_terms), np.zeros(len(v)))

    def _refuse_partial(self) -> None:
        if self.K_free is not None:
            raise ValueError(
                "this evaluation holds the tangent's free-free and free-constrained blocks only "
                "(K_free, K_fc); evaluate with full=True for the whole of it"
            )


@dataclass(frozen=True, eq=False)
class Layout:
    """The design as the analysis sees it, per cell over all bodies (n_cells,).

    rho : stiffness factor (SIMP); mass : material share scaling the volume loads, or None (every
    cell full: the loads of the model as given). Build it checked with :meth:`Discretization.layout`.
    """

    rho: np.ndarray
    mass: np.ndarray | None = None


@dataclass(frozen=True, eq=False)
class Discretization:
    """Everything precomputed from a model; see the module docstring."""

    model: Model
    blocks: tuple
    n_dofs: int
    n_cells: int
    pattern: SparsePattern
    constrained: np.ndarray
    free: np.ndarray
    free_pattern: SubPattern
    fc_pattern: SubPattern  # the free rows' entries in constrained columns (the prescribed increment's)
    f_ext_unit: np.ndarray
    chunk: int
    f_volume: sp.csr_matrix | None = None  # (n_dofs, n_cells): nodal forces of the volume loads per cell
    springs: np.ndarray | None = None  # (n_dofs,) soft-support stiffness at t = 0 (fades as 1 - t), or None
    comm: Comm = SERIAL  # the ranks the cells are split over (contopt.parallel)

    @property
    def has_volume_loads(self) -> bool:
        return self.f_volume is not None and self.f_volume.nnz > 0

    # -------------------------------------------------------------- helpers
    def body_slice(self, name_or_index) -> slice:
        """Dof range of one body in the stacked vector."""
        i = name_or_index if isinstance(name_or_index, int) else self.model.body_index(name_or_index)
        b = self.blocks[i]
        start = 3 * b.node_offset
        return slice(start, start + 3 * b.n_nodes)

    def cell_slice(self, name_or_index) -> slice:
        i = name_or_index if isinstance(name_or_index, int) else self.model.body_index(name_or_index)
        b = self.blocks[i]
        return slice(b.cell_offset, b.cell_offset + b.n_cells)

    def body_displacement(self, u: np.ndarray, name_or_index) -> np.ndarray:
        """(n_nodes, 3) displacement of one body."""
        return u[self.body_slice(name_or_index)].reshape(-1, 3)

    def check_rho(self, rho) -> np.ndarray:
        if rho is None:
            return np.ones(self.n_cells)
        rho = np.asarray(rho, dtype=np.float64).reshape(-1)
        if rho.shape != (self.n_cells,):
            raise ConfigError(f"rho must have one value per cell ({self.n_cells} over all bodies), got {rho.shape}")
        if not np.all(np.isfinite(rho)) or (rho <= 0).any():
            raise ConfigError("rho (stiffness factor per cell) must be finite and > 0 (use SIMP's nu0 floor)")
        return rho

    def check_mass(self, mass) -> np.ndarray | None:
        """None (every cell full: the loads of the model as given) or (n_cells,) finite values >= 0."""
        if mass is None:
            return None
        mass = np.asarray(mass, dtype=np.float64).reshape(-1)
        if mass.shape != (self.n_cells,):
            raise ConfigError(f"mass must have one value per cell ({self.n_cells} over all bodies), got {mass.shape}")
        if not np.all(np.isfinite(mass)) or (mass < 0).any():
            raise ConfigError("mass (material share per cell, scaling the volume loads) must be finite and >= 0")
        return mass

    def layout(self, rho=None, mass=None) -> Layout:
        """A checked :class:`Layout` (rho default: ones)."""
        return Layout(rho=self.check_rho(rho), mass=self.check_mass(mass))

    def f_ext(self, mass=None) -> np.ndarray:
        """(n_dofs,) external load at load factor 1 with the volume loads scaled per cell by ``mass``."""
        mass = self.check_mass(mass)
        if mass is None or not self.has_volume_loads:
            return self.f_ext_unit
        assert self.f_volume is not None  # has_volume_loads
        return self.f_ext_unit + self.f_volume @ (mass - 1.0)

    def spring_stiffness(self, t: float) -> np.ndarray | None:
        """(n_dofs,) soft-support stiffness ``(1 - t) k`` at load factor t; None when there is none."""
        if self.springs is None or t >= 1.0:
            return None
        return (1.0 - t) * self.springs

    def residual_mass_vjp(self, w: np.ndarray, t: float = 1.0) -> np.ndarray:
        """``w . dr/dmass`` (n_cells,): ``r = f_int - t f_ext(mass)`` depends on mass through the volume loads."""
        if not self.has_volume_loads:
            return np.zeros(self.n_cells)
        assert self.f_volume is not None  # has_volume_loads
        return -t * (self.f_volume.T @ w)

    def prescribed(self, t: float) -> np.ndarray:
        """Values (len(constrained),) of the constrained dofs at load factor t."""
        vals = np.zeros(self.n_dofs)
        for bc in self.model.dirichlet:
            i = self.model.body_index(bc.body)
            b, mesh = self.blocks[i], self.model.bodies[i].mesh
            nodes = mesh.node_set(bc.node_set)
            dofs = 3 * (b.node_offset + nodes[:, None]) + bc.component_indices[None, :]
            vals[dofs] = bc.values(mesh.points[nodes], t)
        return vals[self.constrained]

    # ---------------------------------------------------------- physics
    def evaluate(
        self, u: np.ndarray, t: float, rho=None, tangent: bool = True, mass=None, full: bool = True
    ) -> Evaluation:
        """Residual ``f_int(u) - t f_ext(mass)`` (n_dofs,) and, with ``tangent``, ``K_free`` and
        ``K_fc`` (with ``full`` also the whole ``K``; :class:`Evaluation`)."""
        rho = self.check_rho(rho)
        f_ext = self.f_ext(mass)
        tm = Timings()
        r = np.zeros(self.n_dofs)
        energy = 0.0
        # the element tangents go into the CSR data chunk by chunk as the kernels make them: held
        # whole they took 4.6 kB a cell, more than the matrix itself (18 bytes a stored entry)
        data = np.zeros(self.pattern.nnz) if tangent else None
        for i, b in enumerate(self.blocks):
            clock, scattered = Stopwatch(), tm.scatter
            dofs, grad, wdet = b.kernel_inputs()
            We, re, *_ = element_residuals_tangents(
                u[dofs].reshape(-1, b.nodes_per_cell, 3),
                grad,
                wdet,
                rho[b.owned_cells],
                b.params,
                b.energy,
                b.fbar,
                tangent=tangent,
                chunk=self.chunk,
                tangent_sink=None if data is None else partial(self._add_tangents, data, i, tm),
            )
            # the kernels' time without the scatter of their tangents (timed by _add_tangents)
            tm.kernels += clock.seconds - (tm.scatter - scattered)
            with timed(tm, "scatter"):
                energy += float(We.sum())
                _scatter_add(r, dofs, re)
        if self.comm.distributed:
            r, energy = self.comm.sum(r), self.comm.sum(energy)
        r -= t * f_ext
        energy -= t * dot(f_ext, u)  # not BLAS's threaded ddot (contopt.vectors)
        k = self.spring_stiffness(t)
        if k is not None:
            r += k * u
            energy += 0.5 * dot(u, k * u)
        if data is None:
            return Evaluation(r=r, K_terms=None, K_free=None, timings=tm, energy=energy, reduce=self.comm.sum)
        with timed(tm, "scatter"):
            extra: tuple = ()
            if k is not None and self.comm.rank == 0:
                # into the diagonal of the pattern: the same sparsity (the factor's analysis is reused),
                # without a sum of two matrices of the tangent's size
                if self.pattern.diagonal is not None:
                    data[self.pattern.diagonal] += k
                else:
                    extra = (sp.diags(k, format="csr"),)
            terms = (self.pattern.matrix(data), *extra) if full else None
            K_free, K_fc = self.free_pattern.matrix(data), self.fc_pattern.matrix(data)
            del data  # held on only by the whole tangent's terms, when they are asked for
            if extra:
                K_free = (K_free + extra[0][self.free][:, self.free]).tocsr()
        return Evaluation(r=r, K_terms=terms, K_free=K_free, timings=tm, energy=energy, reduce=self.comm.sum, K_fc=K_fc)

    def _add_tangents(self, data: np.ndarray, block: int, tm: Timings, start: int, stop: int, K: np.ndarray) -> None:
        """Add the tangents K (stop - start, 3n, 3n) of owned cells start:stop of ``block`` into data."""
        with timed(tm, "scatter"):
            self.pattern.add_cells(data, block, start, stop, K)

    def residual_rho_vjp(self, u: np.ndarray, w: np.ndarray, rho=None) -> np.ndarray:
        """``w . dr/drho`` (n_cells,) at fixed u: the design part of the adjoint sensitivity (paper eq. 21).

        Only the internal forces depend on rho (the volume loads depend on ``mass``: :meth:`residual_mass_vjp`).
        """
        rho = self.check_rho(rho)
        out = np.zeros(self.n_cells)
        for b in self.blocks:
            dofs, grad, wdet = b.kernel_inputs()
            out[b.owned_cells] = element_rho_vjps(
                u[dofs].reshape(-1, b.nodes_per_cell, 3),
                w[dofs].reshape(-1, b.nodes_per_cell, 3),
                grad,
                wdet,
                rho[b.owned_cells],
                b.params,
                b.energy,
                b.fbar,
                chunk=self.chunk,
            )
        return self.comm.sum(out)

    def strain_energy(self, u: np.ndarray, rho=None, per_cell: bool = False):
        """Total (or per-cell, (n_cells,)) stored energy of all bodies."""
        rho = self.check_rho(rho)
        e = np.zeros(self.n_cells)
        for b in self.blocks:
            dofs, grad, wdet = b.kernel_inputs()
            e[b.owned_cells] = element_energies(
                u[dofs].reshape(-1, b.nodes_per_cell, 3),
                grad,
                wdet,
                rho[b.owned_cells],
                b.params,
                b.energy,
                b.fbar,
                chunk=self.chunk,
            )
        e = self.comm.sum(e)
        return e if per_cell else float(e.sum())

    def cauchy_stress(self, u: np.ndarray, body, rho=None) -> np.ndarray:
        """(m, 3, 3) cell-average Cauchy stress of one body (scaled by its stiffness factor)."""
        i = body if isinstance(body, int) else self.model.body_index(body)
        b = self.blocks[i]
        rho = self.check_rho(rho)[b.owned_cells]
        (dofs, grad, wdet), volume = b.kernel_inputs(), b.geometry.volume
        sig = element_stresses(
            u[dofs].reshape(-1, b.nodes_per_cell, 3), grad, wdet, b.params, b.energy, b.fbar, chunk=self.chunk
        )
        out = np.zeros((b.n_cells, 3, 3))
        out[b.own] = rho[:, None, None] * np.einsum("mq,mqij->mij", wdet / volume[:, None], sig)
        return self.comm.sum(out)


def _scatter_add(r: np.ndarray, dofs: np.ndarray, values: np.ndarray) -> None:
    r += np.bincount(dofs.reshape(-1), weights=values.reshape(-1), minlength=r.size)


def discretize(model: Model, chunk: int = DEFAULT_CHUNK, comm: Comm | None = None) -> Discretization:
    """Precompute geometry, dof numbering, CSR pattern, Dirichlet sets and loads.

    ``comm`` (default :func:`contopt.parallel.world`): the ranks the cells are split over; the
    sparsity pattern is that of this rank's cells.

    Switches JAX to float64 (an explicit, idempotent call: the kernels must
    never run in single precision, whoever calls them).
    """
    enable_x64()
    comm = comm or world()
    check_mesh_size(sum(b.mesh.n_cells for b in model.bodies), "the model", "use coarser meshes")
    blocks, geometries, node_off, cell_off = [], [], 0, 0
    for body in model.bodies:
        mesh = body.mesh
        geo = cell_geometry(mesh.points, mesh.cells)
        own = cell_range(mesh.n_cells, comm)
        dofs = (3 * (node_off + mesh.cells[:, :, None]) + np.arange(3)).reshape(mesh.n_cells, 3 * mesh.cells.shape[1])
        geometries.append(geo)
        blocks.append(
            BodyBlock(
                name=body.name,
                geometry=_owned_geometry(geo, own) if comm.distributed else geo,
                volume=geo.volume,
                dofs=dofs,
                params=body.material.params,
                energy=body.material.energy,
                fbar=body.fbar and mesh.element == "hex8",  # F-bar is hex8's (Body's docstring)
                node_offset=node_off,
                cell_offset=cell_off,
                n_nodes=mesh.n_nodes,
                n_cells=mesh.n_cells,
                own=own,
            )
        )
        node_off += mesh.n_nodes
        cell_off += mesh.n_cells
    n_dofs = 3 * node_off
    pattern = SparsePattern.from_blocks(n_dofs, [b.dofs[b.own] for b in blocks])
    constrained = _constrained_dofs(model, blocks)
    free = np.setdiff1d(np.arange(n_dofs), constrained)
    f_surface, f_volume = _external_load(model, blocks, geometries, n_dofs, cell_off)
    if free.size == 0:
        raise ConfigError("every dof is prescribed: nothing to solve for")
    return Discretization(
        model=model,
        blocks=tuple(blocks),
        n_dofs=n_dofs,
        n_cells=cell_off,
        pattern=pattern,
        constrained=constrained,
        free=free,
        free_pattern=pattern.restrict(free),
        fc_pattern=pattern.restrict(free, constrained),
        f_ext_unit=f_surface + np.asarray(f_volume.sum(axis=1)).ravel(),
        chunk=chunk,
        f_volume=f_volume,
        springs=_springs(model, blocks, geometries, n_dofs),
        comm=comm,
    )


def _constrained_dofs(model: Model, blocks) -> np.ndarray:
    out = []
    for bc in model.dirichlet:
        i = model.body_index(bc.body)
        nodes = model.bodies[i].mesh.node_set(bc.node_set)
        out.append((3 * (blocks[i].node_offset + nodes[:, None]) + bc.component_indices[None, :]).ravel())
    return np.unique(np.concatenate(out)) if out else np.zeros(0, np.int64)


def _owned_geometry(geo: CellGeometry, own: slice) -> CellGeometry:
    """The geometry of the cells ``own`` (copies: a view would keep every cell's alive)."""
    return CellGeometry(grad=geo.grad[own].copy(), wdet=geo.wdet[own].copy(), volume=geo.volume[own].copy(), N=geo.N)


def _springs(model: Model, blocks, geometries, n_dofs: int) -> np.ndarray | None:
    """(n_dofs,) soft-support stiffness: ``k`` times each node's lumped volume ``sum_e int N_a dV``."""
    if not model.soft_supports:
        return None
    k = np.zeros(n_dofs)
    for support in model.soft_supports:
        i = model.body_index(support.body)
        b, geo = blocks[i], geometries[i]
        lumped = np.einsum("qa,mq->ma", geo.N, geo.wdet)
        _scatter_add(k, b.dofs, support.stiffness * np.repeat(lumped, 3, axis=1))
    return k


def _external_load(model: Model, blocks, geometries, n_dofs: int, n_cells: int) -> tuple[np.ndarray, sp.csr_matrix]:
    """Nodal forces at load factor 1: tractions (n_dofs,) and volume loads per cell (n_dofs, n_cells)."""
    f = np.zeros(n_dofs)
    rows, cols, vals = [], [], []
    for load in model.loads:
        i = model.body_index(load.body)
        body, b, geo = model.bodies[i], blocks[i], geometries[i]
        mesh = body.mesh
        if isinstance(load, Traction):
            facets = mesh.facet_set(load.facet_set)
            N, wda, _ = face_quadrature(mesh.points, mesh.cells, facets)
            fa = np.einsum("kqa,kq,i->kai", N, wda, np.asarray(load.traction))
            dofs = b.dofs[facets[:, 0]]
            _scatter_add(f, dofs, fa.reshape(dofs.shape))
        else:
            force = (
                np.asarray(load.force)
                if isinstance(load, BodyForce)
                else -body.material.mass_density * np.asarray(load.acceleration)
            )
            fa = np.einsum("qa,mq,i->mai", geo.N, geo.wdet, force)
            rows.append(b.dofs.ravel())
            cols.append(np.repeat(b.cell_offset + np.arange(b.n_cells), b.dofs.shape[1]))
            vals.append(fa.reshape(-1))
    if not rows:
        return f, sp.csr_matrix((n_dofs, n_cells))
    V = sp.coo_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n_dofs, n_cells)
    ).tocsr()
    V.sum_duplicates()
    return f, V
