"""Recover the paper's die (section 7.1) from what its text states: sweep the readings it allows.

    python benchmarks/die_recovery.py --out bench-out/die_recovery_coarse.json --grey   # the sweep
    python benchmarks/die_recovery.py --out bench-out/die_recovery_gap.json --fit-gap 3,1.5
    python benchmarks/die_recovery.py --out bench-out/die_recovery_opt.json --optimize 3,0.4045,bottom \
        [--optimize R,GAP,SUPPORT[,DESIGN[,OPTIMIZER]] ...] [--mesh coarse|fine]
    python benchmarks/die_recovery.py --out bench-out/die_recovery_pl.json --grid puso-laursen --grey
    python benchmarks/die_recovery.py --out bench-out/die_recovery_pl_opt.json --optimize pl,2.5,bottom \
        --optimize pl,2.5,right   # pl,X,SUPPORT: Puso & Laursen's die (issue 42) with its axis at x = X
    python benchmarks/die_recovery.py --out bench-out/die_recovery_quick.json --quick   # the grid's first reading
    python benchmarks/die_recovery.py --out bench-out/pl_picture.json --picture pl,2.5,right=PNG   # its deformed state
    python benchmarks/die_recovery.py --plot-tables PNG   # bars of TABLE_ROWS

The paper fixes the slab (9 x 4 x 3, E 1 / nu 0.3), the die's material (E 1000 / nu 0.3) and mesh
(12 x 8 x 1), that the die "initially rest[s] on top of the slab before its contact lines displace
-0.6 in z", 6 load steps, and the full design's slab energy |f_a^0| = 5.014e-2 on the 23 x 10 x 8
mesh. It does not state the die's radius, arc, width along y, thickness, where the motion is
prescribed, or where along x the die sits. Each *reading* is one choice of those (:class:`Reading`);
this script solves the full-design forward problem of every reading of a grid on the coarse mesh and
writes (``paper_energy``, ``rows``), per reading, the slab's strain ``energy``, its ratio to the paper's
(``energy_over_paper``), the total ``contact_force`` and the largest nodal pressure (``max_pressure``), and
(``--grey``) the largest nodal pressure of the uniform grey start
nu = 0.4 of section 7.3 (the paper: "about 1e-2"). ``--fit-gap`` finds, per radius, the gap
between die and slab before the motion for which the energy is the paper's; ``--optimize`` runs
the paper's optimization on a reading's die. docs/die.md reports what these gave.

Motions ("where the motion is prescribed"):

``whole``  the die's inner surface moves by (0, 0, -0.6): an effectively rigid die (the files' choice)
``edges``  only the die's two straight arc ends (its "lines" in the lateral view) move by
           (0, 0, -0.6); the shell between them bends under the contact pressure
``bottom`` only the die's lowest line of inner nodes (under its axis) moves by (0, 0, -0.6), the
           rest of the die follows elastically
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import json
import sys
import time
from pathlib import Path

import numpy as np

from contopt.config import setup_jax

PAPER_ENERGY = 5.014e-2  # |f_a^0| of section 7.1 on the 23 x 10 x 8 mesh
SLAB = (9.0, 4.0, 3.0)
MOTIONS = ("whole", "edges", "bottom")


@dataclasses.dataclass(frozen=True)
class Reading:
    """One reading of the die: outer radius, arc (degrees), width along y, radial thickness,
    where its motion is prescribed (:data:`MOTIONS`), x of its axis, the slab's support, and the
    gap between the die and the slab's top before the motion (the text says "resting": 0; with a
    gap g the die indents the slab by 0.6 - g)."""

    radius: float
    arc_deg: float
    width: float
    thickness: float
    motion: str = "whole"
    x: float = 4.5
    support: str = "bottom"
    gap: float = 0.0

    def __post_init__(self):
        if self.motion not in MOTIONS:
            raise ValueError(f"motion must be one of {MOTIONS}, got {self.motion!r}")
        if not 0.0 < self.thickness < self.radius:
            raise ValueError(f"thickness must lie in (0, radius), got {self.thickness} for radius {self.radius}")

    @property
    def name(self) -> str:
        return (
            f"R{self.radius:g}-arc{self.arc_deg:g}-w{self.width:g}-t{self.thickness:g}-{self.motion}"
            f"-x{self.x:g}-{self.support}" + (f"-gap{self.gap:.4f}" if self.gap else "")
        )

    def overrides(self) -> dict:
        """Overrides of the bundled die-slab/die-cantilever files for this reading."""
        top = SLAB[2]
        out = {
            "bodies[1].mesh.radius": self.radius,
            "bodies[1].mesh.arc_deg": self.arc_deg,
            "bodies[1].mesh.width": self.width,
            "bodies[1].mesh.thickness": self.thickness,
            # the lowest outer line rests on the slab's top (or ``gap`` above it)
            "bodies[1].mesh.center": [self.x, SLAB[1] / 2, top + self.radius + self.gap],
        }
        slab_support = {"body": "slab", "set": "zmin" if self.support == "bottom" else "xmax", "components": "xyz"}
        out["supports"] = [dict(slab_support, value=0.0)] + [
            {"body": "die", "set": s, "components": "xyz", "value": [0.0, 0.0, -0.6]} for s in self.die_sets
        ]
        if self.motion == "bottom":
            # the die's lowest line: its nodes (inner and outer) under the axis
            out["bodies[1].sets"] = [{"name": "bottom_line", "from": "all", "x": [self.x, self.x]}]
        return out

    @property
    def die_sets(self) -> tuple[str, ...]:
        """The die's sets whose nodes move by (0, 0, -0.6)."""
        return {"whole": ("inner",), "edges": ("arc_start", "arc_end"), "bottom": ("bottom_line",)}[self.motion]


def full_width(radius: float, **kw) -> Reading:
    """A full-width die (0.3 overhang a side), 0.3 thick, whose arc covers its contact zone."""
    return Reading(radius, 100.0 if radius >= 2 else 150.0, 4.6, 0.3, **kw)


def puso_laursen(x: float = 2.5, support: str = "bottom") -> Reading:
    """Puso & Laursen's example 2 die as issue 42 quotes a port of it: R 3, 0.2 thick, 5.2 wide, its
    axis 2.5 from the slab's end (x = 2.5, or 6.5 from the other end), resting on the slab and moved
    -0.6 as the seed paper's text says (frictionless; their own example presses 1.4 and slides 4)."""
    return Reading(3.0, 100.0, 5.2, 0.2, "whole", x=x, support=support)


def _slab_energy(system, u, rho=None) -> float:
    disc = system.disc
    return float(disc.strain_energy(u, rho, per_cell=True)[disc.cell_slice("slab")].sum())


def model_of(r: Reading, mesh: str = "coarse"):
    """The Model of a reading (the bundled file with the reading's die)."""
    from contopt.cases.die_slab import FILES
    from contopt.cases.optimization import OPTIMIZATION_CASES
    from contopt.cases.spec import load_spec

    path = OPTIMIZATION_CASES[FILES[r.support]].path
    overrides = r.overrides()
    return load_spec(path, overrides, mesh=mesh, label=path.name, check=False).model


def solve(r: Reading, mesh: str = "coarse", grey: bool = False) -> dict:
    from contopt.solve.newton import NewtonOptions
    from contopt.solve.static import solve_static
    from contopt.solve.system import System

    model = model_of(r, mesh)
    system = System.of(model)
    t0 = time.perf_counter()
    row = {"reading": dataclasses.asdict(r), "name": r.name, "mesh": mesh}
    try:
        state = solve_static(system, newton=NewtonOptions(n_steps=6))
    except Exception as exc:  # a reading that does not converge is a result too
        row.update(error=f"{type(exc).__name__}: {exc}".splitlines()[0], seconds=time.perf_counter() - t0)
        return row
    lam = tuple(c.lam for c in state.contact)
    energy = _slab_energy(system, state.u)
    row.update(
        energy=energy,
        energy_over_paper=energy / PAPER_ENERGY,
        contact_force=float(system.contact.total_force(state.u, lam).sum()),
        max_pressure=float(max(np.max(x) for x in lam)),
        active_nodes=int(sum(c.n_active for c in state.contact)),
        newton=int(state.newton_iterations),
        seconds=time.perf_counter() - t0,
    )
    if grey:
        row.update(_grey(system))
    return row


def _grey(system) -> dict:
    """The uniform grey start of 7.3: nu = 0.4 everywhere in the slab, SIMP p 3, nu0 0.01."""
    from contopt.design.maps import simp
    from contopt.solve.newton import NewtonOptions
    from contopt.solve.static import solve_static

    disc = system.disc
    rho = np.ones(disc.n_cells)
    rho[disc.cell_slice("slab")] = simp(np.array(0.4), 3.0, 0.01)
    try:
        state = solve_static(system, rho, newton=NewtonOptions(n_steps=6))
    except Exception as exc:
        return {"grey_error": f"{type(exc).__name__}: {exc}".splitlines()[0]}
    lam = np.concatenate([c.lam for c in state.contact])
    active = lam[lam > 0]
    return {
        "grey_max_pressure": float(lam.max()),
        "grey_median_active_pressure": float(np.median(active)) if active.size else 0.0,
        "grey_energy": _slab_energy(system, state.u, rho),
    }


def grid(kind: str) -> list[Reading]:
    """The readings of a named grid (``--grid``)."""
    radii = (1.0, 2.0, 3.0, 4.5, 6.0)
    if kind == "coarse":
        # a full-width die (0.3 overhang each side) of every radius, under both supports; the arc
        # covers the contact zone, and at E = 1000 a thickness of 0.3 is rigid
        full = [full_width(R, support=s) for s, R in itertools.product(("bottom", "right"), radii)]
        # a shell thin enough to bend between its prescribed arc ends; a die narrower than the slab
        other = [
            Reading(3.0, 100.0, 4.6, 0.05, "edges"),
            Reading(3.0, 100.0, 4.6, 0.3, "bottom"),
            Reading(3.0, 100.0, 1.0, 0.3, "whole"),
        ]
        return full + other
    if kind == "puso-laursen":
        return [puso_laursen(x, s) for s, x in itertools.product(("bottom", "right"), (2.5, 6.5))]
    raise ValueError(f"unknown grid {kind!r}")


def fit_gap(base: Reading, mesh: str = "coarse", rtol: float = 3e-3, max_solves: int = 8) -> dict:
    """The gap for which ``base``'s die gives the paper's |f_a^0| (within ``rtol``), by secant steps
    on log(energy) against log(indentation 0.6 - gap) (a power law to within a few % here)."""
    d = [0.6 - base.gap]
    rows = [solve(dataclasses.replace(base, gap=0.6 - d[0]), mesh)]
    slope = 2.5  # a line contact: energy ~ d^2.5 to begin with
    guess = d[0] * (PAPER_ENERGY / rows[0]["energy"]) ** (1 / slope)
    while len(rows) < max_solves:
        d.append(guess)
        rows.append(solve(dataclasses.replace(base, gap=0.6 - guess), mesh, grey=False))
        e = [r["energy"] for r in rows[-2:]]
        if abs(e[-1] / PAPER_ENERGY - 1.0) < rtol:
            break
        slope = np.log(e[1] / e[0]) / np.log(d[-1] / d[-2])
        guess = d[-1] * (PAPER_ENERGY / e[-1]) ** (1.0 / slope)
    from contopt.solve.system import System

    best = dataclasses.replace(base, gap=0.6 - d[-1])
    final = {**rows[-1], **_grey(System.of(model_of(best, mesh)))}
    return {"base": dataclasses.asdict(base), "solves": rows, "fit": final, "exponent": float(slope)}


def optimize_reading(
    r: Reading, design: str = "bspline", mesh: str = "coarse", optimizer: str = "mma", n_steps: int | None = None
) -> dict:
    """The paper's optimization (7.1 for the bottom support, 7.2 for the right) on a reading's die,
    with benchmarks/paper_tables.py's stopping rules; f/|f_a^0| to set beside tables 1 and 3.
    n_steps: the load steps of a solve from zero (default: the file's ``newton.n_steps``)."""
    from contopt.cases.die_slab import FILES
    from contopt.cases.optimization import OPTIMIZATION_CASES
    from contopt.cases.spec import load_spec
    from contopt.optimize.driver import optimize
    from contopt.optimize.ipopt import IpoptOptions
    from contopt.optimize.mma import MMAOptions

    path = OPTIMIZATION_CASES[FILES[r.support]].path
    overrides = r.overrides() | ({} if n_steps is None else {"newton.n_steps": n_steps})
    problem = load_spec(path, overrides, mesh=mesh, design=design, label=path.name, check=False).problem
    from paper_tables import IPOPT_TOL, MMA_KKT_TOL

    mma = MMAOptions(max_iter=100, kkt_tol=MMA_KKT_TOL, change_tol=0.0)
    options = mma if optimizer == "mma" else IpoptOptions(tol=IPOPT_TOL)
    t0 = time.perf_counter()
    res = optimize(problem, optimizer, options)
    return {
        "reading": dataclasses.asdict(r),
        "name": r.name,
        "design": design,
        "mesh": mesh,
        "optimizer": optimizer,
        "n_steps": n_steps,
        "normalized_objective": float(res.normalized_objective),
        "full_energy": float(abs(res.scale)),
        "iterations": int(res.iterations),
        "status": res.status,
        "seconds": time.perf_counter() - t0,
    }


#: f/|f_a^0| beside the paper's (docs/die.md, "Puso & Laursen's die"): (row, paper, the fitted die
#: (bundled), Puso & Laursen's die resting and moved -0.6); coarse rows from ``--optimize`` (MMA), the
#: fitted die's from docs/results.md (benchmarks/paper_tables.py); the paper gives table 3's fine rows only
TABLE_ROWS = (
    ("table 1, coarse B-spline", -0.9908, -0.9450, -0.9222),
    ("table 3, coarse B-spline", -0.6928, -0.8439, -0.6842),
    ("table 3, coarse density", -0.6974, -0.8457, -0.6898),
)


def plot_tables(figure: Path, rows=TABLE_ROWS) -> Path:
    """Bars of f/|f_a^0| per table row: the paper's, the fitted die's and Puso & Laursen's die's."""
    from contopt.io.plots import _pyplot, _save

    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 3.6))
    x = np.arange(len(rows))
    labels = ("paper (table 3: its fine rows)", "fitted die (bundled)", "Puso & Laursen's die, resting, -0.6")
    for k, label in enumerate(labels):
        values = [-r[k + 1] for r in rows]
        bars = ax.bar(x + (k - 1) * 0.27, values, 0.27, label=label, color=("0.3", "C0", "C3")[k])
        ax.bar_label(bars, labels=[f"{v:.3f}" for v in values], fontsize=7, padding=1)
    ax.set_xticks(x, [r[0] for r in rows], fontsize=8)
    ax.set_ylabel("-f / |f_a^0| (energy kept)")
    ax.set_ylim(0.5, 1.05)
    ax.legend(fontsize=7, loc="upper right")
    ax.set_title("The seed paper's tables 1 and 3 on two dies (MMA)", fontsize=9)
    fig.tight_layout()
    return _save(plt, fig, figure)


def picture(r: Reading, path: Path, mesh: str = "coarse") -> dict:
    """The full design's forward solve of a reading (6 load steps) and a picture of its last state."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from validation import deformed_picture

    from contopt.solve.newton import NewtonOptions
    from contopt.solve.static import solve_static
    from contopt.solve.system import System

    system = System.of(model_of(r, mesh))
    state = solve_static(system, newton=NewtonOptions(n_steps=6))
    title = f"{r.name}, {mesh} mesh: slab energy {_slab_energy(system, state.u):.4g}"
    deformed_picture(system, state, path, up="z", title=title)
    return {"name": r.name, "energy": _slab_energy(system, state.u), "picture": str(path)}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", help="the JSON to write (all but --plot-tables)")
    p.add_argument("--grid", choices=["coarse", "puso-laursen"], default="coarse")
    p.add_argument("--mesh", default="coarse")
    p.add_argument("--grey", action="store_true", help="also solve the uniform grey start of 7.3")
    p.add_argument(
        "--fit-gap",
        default=None,
        help="radii (comma-separated): for each, the gap before the motion that gives the paper's |f_a^0|",
    )
    p.add_argument(
        "--optimize",
        action="append",
        default=[],
        metavar="R,GAP,SUPPORT[,DESIGN[,OPTIMIZER]]",
        help="optimize on this reading's die (table 1: bottom, table 3: right); repeatable",
    )
    p.add_argument("--n-steps", type=int, default=None, help="--optimize: load steps of a solve (default: the file's)")
    p.add_argument("--quick", action="store_true", help="solve the grid's first reading only (seconds)")
    p.add_argument(
        "--picture", metavar="READING=PNG", help="a picture of a reading's (R,GAP,SUPPORT or pl,X,SUPPORT) full design"
    )
    p.add_argument("--plot-tables", metavar="PNG", help="bars of TABLE_ROWS: the tables on the two dies")
    args = p.parse_args(argv)
    if args.plot_tables:
        plot_tables(Path(args.plot_tables))
        return 0
    if not args.out:
        p.error("--out is required")
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    planned = [_optimize_arg(p, text) for text in args.optimize]
    setup_jax()
    if args.picture:
        reading, _, png = args.picture.partition("=")
        if not png:
            p.error(f"--picture {args.picture}: give READING=PNG, e.g. pl,2.5,right=die.png")
        row = picture(_optimize_arg(p, reading)[0], Path(png), args.mesh)
        print(json.dumps(row))
        out.write_text(json.dumps(row, indent=1))
        return 0
    if planned:
        runs = []
        for r, rest in planned:
            runs.append(optimize_reading(r, *rest, mesh=args.mesh, n_steps=args.n_steps))
            print(json.dumps(runs[-1]))
            out.write_text(json.dumps({"paper_energy": PAPER_ENERGY, "optimizations": runs}, indent=1))
        return 0
    if args.fit_gap:
        fits = []
        for radius in (float(v) for v in args.fit_gap.split(",")):
            base = full_width(radius)
            fits.append(fit_gap(base, args.mesh))
            f = fits[-1]["fit"]
            print(json.dumps({k: f.get(k) for k in ("name", "energy", "energy_over_paper", "grey_max_pressure")}))
            out.write_text(json.dumps({"paper_energy": PAPER_ENERGY, "fits": fits}, indent=1))
        return 0
    rows = []
    for r in grid(args.grid)[:1] if args.quick else grid(args.grid):
        row = solve(r, args.mesh, args.grey)
        rows.append(row)
        print(json.dumps({k: row.get(k) for k in ("name", "energy", "energy_over_paper", "max_pressure", "error")}))
        out.write_text(json.dumps({"paper_energy": PAPER_ENERGY, "rows": rows}, indent=1))
    return 0


def _optimize_arg(p: argparse.ArgumentParser, text: str) -> tuple[Reading, list[str]]:
    """``R,GAP,SUPPORT[,DESIGN[,OPTIMIZER]]`` as a reading and the rest; a malformed one is a usage error."""
    parts = text.split(",")
    try:
        if not 3 <= len(parts) <= 5 or parts[2] not in ("bottom", "right"):
            raise ValueError
        if parts[0] == "pl":  # pl,X,SUPPORT: Puso & Laursen's die with its axis at x = X
            return puso_laursen(float(parts[1]), parts[2]), parts[3:]
        return full_width(float(parts[0]), gap=float(parts[1]), support=parts[2]), parts[3:]
    except ValueError:
        p.error(f"--optimize {text!r}: expected R,GAP,bottom|right[,bspline|density[,mma|ipopt]] or pl,X,...")


if __name__ == "__main__":
    sys.exit(main())
