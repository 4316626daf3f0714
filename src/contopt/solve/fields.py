"""What a state shows, body by body: the fields a run writes for ParaView.

Per body: the point data ``displacement`` (n_nodes, 3) and the cell data ``cauchy_stress``
(n_cells, 9, row-major), ``von_mises`` (n_cells,) and ``rho_tilde`` (n_cells,) (the physical
density). :mod:`contopt.io.vtk` writes them; it computes nothing.
"""

from __future__ import annotations

import numpy as np

from contopt.assembly.system import Discretization


def von_mises(sigma: np.ndarray) -> np.ndarray:
    """Von Mises equivalent stress of (..., 3, 3) Cauchy stresses."""
    s = sigma - np.trace(sigma, axis1=-2, axis2=-1)[..., None, None] * np.eye(3) / 3.0
    return np.sqrt(1.5 * np.sum(s * s, axis=(-2, -1)))


def body_fields(disc: Discretization, u: np.ndarray, rho: np.ndarray | None, body: int | str) -> tuple[dict, dict]:
    """(point data, cell data) of one body (its index or name) at displacement ``u`` (n_dofs,) and
    physical density ``rho`` (n_cells,; None: solid)."""
    i = body if isinstance(body, int) else disc.model.body_index(body)
    rho = disc.check_rho(rho)
    sigma = disc.cauchy_stress(u, i, rho)
    point_data = {"displacement": disc.body_displacement(u, i)}
    cell_data = {
        "cauchy_stress": sigma.reshape(len(sigma), 9),
        "von_mises": von_mises(sigma),
        "rho_tilde": rho[disc.cell_slice(i)],
    }
    return point_data, cell_data


def state_fields(disc: Discretization, u: np.ndarray, rho: np.ndarray | None) -> dict[str, tuple[dict, dict]]:
    """:func:`body_fields` of every body, by name."""
    return {b.name: body_fields(disc, u, rho, i) for i, b in enumerate(disc.model.bodies)}
