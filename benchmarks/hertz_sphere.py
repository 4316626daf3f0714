"""Hertz sphere contact with the deformable body in tet10 or hex8 (issue 39 §1).

    python benchmarks/hertz_sphere.py --out bench-out/hertz_sphere.json [--quick] [--h H] [--element hex8|tet10|both]
        [--d D] [--length L] [--ratio G] [--cap N] [--equal-accuracy [--refine R] [--max-refine K]]

A rigid sphere (R = 1, an equiangular cap of 34 x 34 facets spanning 3 a0, a0 = sqrt(R d) Hertz's
contact radius for d: 0.018 wide at d = 0.01; ``--cap N``: N x N) pressed ``--d`` (default 0.01,
a/R = 0.1) into a quarter block (E = 1, nu = 0.3, symmetry planes x = 0 and y = 0, clamped at its
bottom), the model of tests/contact/test_rigid_tool.py ``test_hertz_against_a_rigid_sphere``: cells
of ``h`` up to 1.5 a0 from the axis and the surface, graded ``--ratio`` (1.4) x beyond to
``--length`` (2.5; ``--quick``: h = 0.04 and length 1.0, a few seconds once compiled). The block is
the nonmortar side: hex8 as generated, or tet10 (``contopt.mesh.tets.tetrahedralize(..., order=2)``:
six tets a hex, its top faces tri6 and integrated by the quadratic mortar kernels, docs/contact.md
"Triangle facets").

Read from the FE field, against Hertz for the force the contact carries (``F``, the whole sphere's:
4 x the quarter's pressure resultant ``sum lam_A a_A``): ``p0`` the peak nodal pressure (the node on
the axis) against ``3 F / (2 pi a^2)``; ``a`` from the pressure's second moment,
``int r^2 p da / int p da = 2 a^2 / 5`` (the nodal multipliers interpolated bilinearly on the hex8
facets, 2x2 Gauss; on tet10 the field ``sum_A lam_A W_A`` on the tri6 parents' curved surface,
:func:`second_moment`), against ``a = (3 F R / (4 E*))^(1/3)``; ``p0_fit``, ``a_fit`` of
the elliptic fit ``p^2 = p0^2 (1 - r^2 / a^2)`` to the nodes with pressure (least squares). On tet10
the nodal values are those of the pressure field ``sum_A lam_A W_A`` (:func:`nodal_pressures`: a
midpoint's multiplier is not its pressure); and ``F`` against Hertz's
``4/3 E* sqrt(R) d^(3/2)`` for the indentation d (the finite block and finite strain stiffen it).
The readings ``_ref`` place the same pressures at the nodes' reference positions (at finite strain
the surface under the sphere moves inward: the deformed ``a`` is about ``(1 - 2 nu) / (1 - nu)
2 a / (3 pi R)`` of a smaller, 1.2 % at a/R = 0.1), and ``profile`` lists each node with pressure
(``r``, ``r_ref``, ``p``). Each element runs in its own process, so that ``peak_rss_mb``
(``ru_maxrss``) is its own; ``wall`` is the solve's (the kernels compiled or loaded before it,
reported as ``compile_s``). The JSON's ``rows``, one per run: ``element``, ``n_dofs``,
``n_equations``, ``newton_iterations``, ``wall``, ``peak_rss_mb``, the readings and their relative
errors against Hertz ``error_p0``, ``error_a``, ``error_p0_fit``, ``error_a_fit``, ``error_a_ref``,
``error_p0_fit_ref``, ``error_a_fit_ref`` and ``error_force_d``.

``--equal-accuracy``: accuracy is the error against the mesh-converged answer of the same model (the
same block, sphere and d), not against Hertz, whose half-space at small strain the finite block at
finite strain does not converge to (docs/performance.md "Hertz sphere"). tet10 at ``h``, hex8 at
``h``, ``h / R``, .. ``h / R^K`` (``--refine`` R, default 1.25; ``--max-refine`` K, default 5, at
least 2); each of the :data:`READINGS` (F at d, the second moment's a, the fitted p0) converged from
the three finest hex8 grids (:func:`converged`: Richardson where they converge monotonically, else
their mean), every row's ``error_converged`` against it, a run's accuracy the largest of them. The
JSON's ``equal_accuracy``: ``reference`` (each reading's converged value, method, ``spread``),
``target`` (the tet10's accuracy), ``resolved`` (target above every reference's spread),
``matched`` (a hex8 grid reached it), ``tet10`` and ``hex8`` (the coarsest matching grid, or the
finest) each with ``h``, ``n_dofs``, ``n_equations``, ``wall``, ``peak_rss_mb`` and ``accuracy``,
and ``per_reading``: each reading's tet10 error and the coarsest hex8 grid (``hex8_h``,
``hex8_dofs``) as accurate in it alone.
"""

from __future__ import annotations

import argparse
import json
import platform
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
R, D, NU = 1.0, 0.01, 0.3
E_STAR = 1.0 / (1 - NU**2)
#: cell size near the contact and the block's half-width: full and --quick
H_FULL, H_QUICK, LENGTH_FULL, LENGTH_QUICK = 0.02, 0.04, 2.5, 1.0


def model_of(element: str, h: float, length: float, cap_n: int = 34, d: float = D, ratio: float = 1.4):
    """The rigid sphere pressed ``d`` into a quarter block in ``element`` (hex8 or tet10): (Model, block
    mesh). Cells of h up to 1.5 a0 from the axis and the surface (a0 = sqrt(R d), Hertz's a for d),
    ``ratio`` x longer each beyond; the cap spans 3 a0 (0.3 at d = 0.01)."""
    sys.path.insert(0, str(ROOT / "tests" / "contact"))
    from _meshing import graded

    from contopt.assembly.model import Body, Dirichlet, LoadPath, Model, RigidMotion
    from contopt.contact.interface import ContactInterface
    from contopt.contact.laws import AugmentedLagrangian
    from contopt.material import neo_hookean
    from contopt.mesh.generators import box
    from contopt.mesh.tets import tetrahedralize
    from contopt.mesh.tool import sphere_surface, tool_layer

    a0 = float(np.sqrt(R * d))
    xs = graded(h, 1.5 * a0, length, ratio)
    mesh = box(grading=(xs, xs, -xs[::-1]))
    mesh = tetrahedralize(mesh, 2) if element == "tet10" else mesh
    cap = sphere_surface(R, (0.0, 0.0, R), cap_n, normal=(0.0, 0.0, -1.0), angle=3 * a0)
    path = LoadPath(tuple((t, 0.0, 0.0, -d * t**2) for t in (0.25, 0.5, 0.75, 1.0)))  # touching first
    law = AugmentedLagrangian(eps=10 * E_STAR / h)
    model = Model(
        bodies=(
            Body("block", mesh, neo_hookean(1.0, NU)),
            Body("ball", tool_layer(cap), rigid=RigidMotion(translation=path)),
        ),
        dirichlet=(Dirichlet("block", "zmin", "xyz"), Dirichlet("block", "xmin", "x"), Dirichlet("block", "ymin", "y")),
        interfaces=(ContactInterface(surfaces=(("ball", "surface"), ("block", "zmax")), law=law),),
    )
    return model, mesh


def nodal_pressures(block, lam: np.ndarray) -> np.ndarray:
    """The pressure field's values at the nonmortar nodes (n,): the multipliers themselves, except at
    a tri6 midpoint, whose weight is not interpolatory: there ``p_h = sum_A lam_A W_A`` is
    ``(1 - 2 alpha) lam_m + alpha (lam_a + lam_b)`` over the edge's corners a, b."""
    from contopt.contact.quadratic import TRI6_ALPHA

    par = block.parents
    if par is None or par.kinds[0] != "tri6":
        return lam
    loc = par.nm_local[::4]  # one row a parent face
    out = lam.copy()
    for m, (i, j) in zip((3, 4, 5), ((0, 1), (1, 2), (2, 0))):
        out[loc[:, m]] = (1 - 2 * TRI6_ALPHA) * lam[loc[:, m]] + TRI6_ALPHA * (lam[loc[:, i]] + lam[loc[:, j]])
    return out


def second_moment(block, x: np.ndarray, lam: np.ndarray) -> tuple[float, float]:
    """``(int p_h da, int r^2 p_h da)`` over the deformed nonmortar surface (x (N, 3)), r the distance
    from the z axis: on hex8 facets the nodal multipliers interpolated bilinearly (2x2 Gauss); on tet10
    faces the tri6 parents' curved surface with ``p_h = sum_A lam_A W_A``, the field the multipliers
    define (``contopt.responses.surface``: the same points as ``ContactForce(quadrature="gauss")``)."""
    from contopt.contact.quadratic import TRI6_RULE_WEIGHTS, tri6_surface
    from contopt.responses.surface import nonmortar_faces

    nodes, local = nonmortar_faces(block)
    if nodes.shape[1] != 6:
        sys.path.insert(0, str(ROOT / "tests" / "contact"))
        from _hertz import pressure_moments

        return pressure_moments(x[nodes], lam[local], axes=(0, 1))
    y, da = (np.asarray(v) for v in tri6_surface(x[nodes]))  # (k, q, 3), (k, q)
    p_da = (lam[local] @ TRI6_RULE_WEIGHTS.T) * da
    return float(p_da.sum()), float(np.sum(p_da * np.sum(y[..., :2] ** 2, axis=-1)))


def elliptic_fit(lam: np.ndarray, r2: np.ndarray) -> tuple[float, float]:
    """(p0, a) of the least-squares fit ``lam^2 = p0^2 (1 - r^2 / a^2)`` over the nodes with pressure
    (nan where too few have it: a negative slope)."""
    act = lam > 0
    c0, c1 = np.linalg.lstsq(np.stack([np.ones(act.sum()), -r2[act]], axis=1), lam[act] ** 2, rcond=None)[0]
    with np.errstate(invalid="ignore"):
        return float(np.sqrt(c0)), float(np.sqrt(c0 / c1))


def readings(block, x: np.ndarray, X: np.ndarray, lam: np.ndarray, force: float, d: float) -> dict:
    """The row's readings against Hertz for ``force`` (module docstring): on the deformed surface ``x``,
    and (``_ref``) the same nodal pressures placed at the reference positions ``X``."""
    a_hertz = (3 * force * R / (4 * E_STAR)) ** (1 / 3)
    p0_hertz = 3 * force / (2 * np.pi * a_hertz**2)
    m0, m2 = second_moment(block, x, lam)
    m0_ref, m2_ref = second_moment(block, X, lam)
    p = nodal_pressures(block, lam)
    out = {
        "force": force,
        "force_hertz_d": 4 / 3 * E_STAR * np.sqrt(R) * d**1.5,
        "a_hertz": a_hertz,
        "p0_hertz": p0_hertz,
        "a": float(np.sqrt(2.5 * m2 / m0)),
        "p0": float(p.max()),
        "a_ref": float(np.sqrt(2.5 * m2_ref / m0_ref)),
    }
    out["p0_fit"], out["a_fit"] = elliptic_fit(p, np.sum(x[block.nodes][:, :2] ** 2, axis=1))
    out["p0_fit_ref"], out["a_fit_ref"] = elliptic_fit(p, np.sum(X[block.nodes][:, :2] ** 2, axis=1))
    act = p > 0  # the profile: each node with pressure, its radius (deformed, reference) and pressure
    r_def, r_ref = (np.linalg.norm(y[block.nodes][act, :2], axis=1) for y in (x, X))
    out["profile"] = {"r": r_def.tolist(), "r_ref": r_ref.tolist(), "p": p[act].tolist()}
    for k in ("a", "a_ref", "a_fit", "a_fit_ref"):
        out[f"error_{k}"] = out[k] / a_hertz - 1
    for k in ("p0", "p0_fit", "p0_fit_ref"):
        out[f"error_{k}"] = out[k] / p0_hertz - 1
    out["error_force_d"] = force / out["force_hertz_d"] - 1
    return out


def run(element: str, h: float, length: float, cap_n: int = 34, d: float = D, ratio: float = 1.4) -> dict:
    """Solve one element's model; its row of the JSON."""
    from contopt.contact.mortar import precompile
    from contopt.solve.newton import NewtonOptions
    from contopt.solve.static import AugmentationOptions, solve_static
    from contopt.solve.system import System

    model, mesh = model_of(element, h, length, cap_n, d, ratio)
    t0 = time.perf_counter()
    precompile()
    if element == "tet10":
        from contopt.contact.quadratic import precompile as precompile_quadratic

        precompile_quadratic(("tri6", "quad"))
    compile_s = time.perf_counter() - t0
    system = System.of(model)
    t0 = time.perf_counter()
    state = solve_static(
        system,
        newton=NewtonOptions(n_steps=4, rtol=1e-10),
        augmentation=AugmentationOptions(pressure_rtol=1e-8, gap_rtol=1e-8),
    )
    wall = time.perf_counter() - t0
    lam = state.contact[0].lam
    force = 4 * float(system.contact.total_force(state.u, (lam,))[0])  # the whole sphere's
    X = np.asarray(system.contact.X)
    x = X + state.u.reshape(-1, 3)
    return {
        "element": element,
        "h": h,
        "length": length,
        "d": d,
        "ratio": ratio,
        "cap": cap_n,
        "n_cells": int(mesh.n_cells),
        "n_dofs": int(system.disc.n_dofs),
        "n_equations": int(system.disc.free.size),
        "newton_iterations": int(state.newton_iterations),
        "compile_s": round(compile_s, 2),
        "wall": round(wall, 2),
        "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0, 1),
        **readings(system.contact.blocks[0], x, X, lam, force, d),
    }


def child(out: Path, element: str, h: float, geo: dict) -> dict:
    """One element's row, solved in a process of its own (its own peak RSS); ``geo``: ``length``,
    ``cap_n``, ``d`` and ``ratio`` of :func:`run`."""
    part = out.with_suffix(f".{element}.{h:.6g}.json")
    cmd = [sys.executable, __file__, "--one", "--element", element, "--h", str(h), "--length", str(geo["length"])]
    cmd += ["--cap", str(geo["cap_n"]), "--d", str(geo["d"]), "--ratio", str(geo["ratio"])]
    subprocess.run([*cmd, "--out", str(part)], check=True)
    row = json.loads(part.read_text())
    part.unlink()
    print(summary(row), flush=True)  # as each run ends: a long --equal-accuracy shows its rows on the way
    return row


def summary(r: dict) -> str:
    """One row's line of the printed report."""
    return (
        f"{r['element']}: h {r['h']:.6g}, {r['n_cells']} cells, {r['n_dofs']} dofs, Newton {r['newton_iterations']}, "
        f"wall {r['wall']:.1f} s (compile {r['compile_s']:.1f} s), peak RSS {r['peak_rss_mb']:.0f} MB; "
        f"p0 {r['error_p0']:+.2%}, a {r['error_a']:+.2%}, "
        f"fit p0 {r['error_p0_fit']:+.2%} a {r['error_a_fit']:+.2%}, force vs d {r['error_force_d']:+.2%}"
    )


#: the readings ``--equal-accuracy`` judges, each against the mesh-converged answer of the same model
READINGS = ("force", "a", "p0_fit")


def converged(values: list, refine: float) -> dict:
    """The mesh-converged value of a reading from its values on the three finest of grids refined by a
    constant factor (coarse to fine): Richardson's extrapolation where they converge monotonically at
    an observed order of at least 1 (``q``, the ratio of successive differences, in (0, 1 / refine]),
    else their mean; ``spread``: their range relative to the value (the reference's own uncertainty)."""
    f1, f2, f3 = (float(v) for v in values[-3:])
    q = (f3 - f2) / (f2 - f1) if f2 != f1 else 0.0
    if 0 < q <= 1 / refine:
        value, method = f3 + (f3 - f2) * q / (1 - q), "richardson"
    else:
        value, method = (f1 + f2 + f3) / 3, "mean"
    return {"value": value, "method": method, "q": q, "spread": (max(f1, f2, f3) - min(f1, f2, f3)) / abs(value)}


def accuracy(row: dict) -> float:
    """The largest relative error of the :data:`READINGS` against the mesh-converged answer
    (``error_converged``); infinite where a reading is not finite (a failed fit: too few nodes with
    pressure give a negative slope, a nan radius)."""
    return max(abs(e) if np.isfinite(e) else np.inf for e in row["error_converged"].values())


def equal_accuracy(out: Path, h: float, geo: dict, refine: float, max_refine: int) -> tuple[list, dict]:
    """tet10 at h, hex8 at h, h / refine, .. h / refine^max_refine, judged by :func:`judge`: (rows,
    the ``equal_accuracy`` record)."""
    tet = child(out, "tet10", h, geo)
    hexes = [child(out, "hex8", h / refine**k, geo) for k in range(max_refine + 1)]
    return [tet, *hexes], judge(tet, hexes, refine)


def judge(tet: dict, hexes: list, refine: float) -> dict:
    """Each reading's mesh-converged value from the three finest of the ``hexes`` (coarse to fine,
    :func:`converged`), every row's ``error_converged`` against it (set in place), and the coarsest
    hex8 grid as accurate as the tet10 against it: the ``equal_accuracy`` record."""

    def brief(row):
        keys = ("h", "n_dofs", "n_equations", "wall", "peak_rss_mb")
        return {**{k: row[k] for k in keys}, "accuracy": accuracy(row)}

    reference = {q: converged([r[q] for r in hexes], refine) for q in READINGS}
    for row in (tet, *hexes):
        row["error_converged"] = {q: row[q] / reference[q]["value"] - 1 for q in READINGS}
    target = accuracy(tet)
    match = next((r for r in hexes if accuracy(r) <= target), None)
    per_reading = {}
    for q in READINGS:
        e = abs(tet["error_converged"][q])
        hit = next((r for r in hexes if abs(r["error_converged"][q]) <= e), None)
        per_reading[q] = {
            "tet10": tet["error_converged"][q],
            "hex8_h": hit and hit["h"],
            "hex8_dofs": hit and hit["n_dofs"],
        }
    return {
        "readings": list(READINGS),
        "reference": reference,
        "target": target,
        "resolved": target > max(ref["spread"] for ref in reference.values()),
        "matched": match is not None,
        "tet10": brief(tet),
        "hex8": brief(match or hexes[-1]),
        "per_reading": per_reading,
    }


def rejudge(path: Path) -> tuple[list, dict]:
    """An earlier ``--equal-accuracy`` JSON's rows judged again (no solve): (rows, record)."""
    rows = json.loads(Path(path).read_text())["rows"]
    tet = next(r for r in rows if r["element"] == "tet10")
    hexes = sorted((r for r in rows if r["element"] == "hex8"), key=lambda r: -r["h"])
    return [tet, *hexes], judge(tet, hexes, hexes[-2]["h"] / hexes[-1]["h"])


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, help="JSON file to write")
    p.add_argument("--quick", action="store_true", help=f"h = {H_QUICK}, length {LENGTH_QUICK}")
    p.add_argument("--h", type=float, default=None, help=f"cell size near the contact (default {H_FULL})")
    p.add_argument("--length", type=float, default=None, help=f"the block's half-width (default {LENGTH_FULL})")
    p.add_argument("--element", choices=["hex8", "tet10", "both"], default="both")
    p.add_argument("--equal-accuracy", action="store_true", help="tet10 at h against hex8 grids at equal accuracy")
    p.add_argument("--refine", type=float, default=1.25, help="hex8's refinement factor of h (--equal-accuracy)")
    p.add_argument("--max-refine", type=int, default=5, help="hex8's refinements (--equal-accuracy; at least 2)")
    p.add_argument("--cap", type=int, default=34, help="the cap's facets a side (default 34; 0.018 wide at d = 0.01)")
    p.add_argument("--d", type=float, default=D, help=f"the indentation (default {D}: a/R = 0.1)")
    p.add_argument("--ratio", type=float, default=1.4, help="the cells' growth beyond 1.5 a (default 1.4)")
    p.add_argument("--rows", type=Path, default=None, help="judge an earlier --equal-accuracy JSON's rows again")
    p.add_argument("--one", action="store_true", help=argparse.SUPPRESS)  # a child: one element, JSON row to --out
    args = p.parse_args(argv)
    h = args.h or (H_QUICK if args.quick else H_FULL)
    length = args.length or (LENGTH_QUICK if args.quick else LENGTH_FULL)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    if args.equal_accuracy and args.max_refine < 2:
        p.error("--equal-accuracy needs --max-refine >= 2 (three hex8 grids for the converged answer)")
    if args.one:
        from contopt.config import setup_jax

        setup_jax()
        out.write_text(json.dumps(run(args.element, h, length, args.cap, args.d, args.ratio), indent=1))
        return 0
    geo = {"length": length, "cap_n": args.cap, "d": args.d, "ratio": args.ratio}
    result: dict = {"machine": {"python": sys.version.split()[0], "platform": platform.platform()}}
    if args.rows:
        rows, result["equal_accuracy"] = rejudge(args.rows)
        result["rows_from"] = str(args.rows)
    elif args.equal_accuracy:
        rows, result["equal_accuracy"] = equal_accuracy(out, h, geo, args.refine, args.max_refine)
    else:
        rows = [child(out, e, h, geo) for e in (["hex8", "tet10"] if args.element == "both" else [args.element])]
    result["rows"] = rows
    out.write_text(json.dumps(result, indent=1))
    if args.equal_accuracy or args.rows:
        print(f"equal accuracy: {json.dumps(result['equal_accuracy'])}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
