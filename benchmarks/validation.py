"""The validation benchmarks of docs/validation.md, run against their sources' reference values (issue 42 §1).

    python benchmarks/validation.py --case CASE --out bench-out/CASE.json [--quick]
    python benchmarks/validation.py --plot bench-out/CASE.json --figure docs/figures/validation/CASE.png
    python benchmarks/validation.py --case CASE --out bench-out/CASE.json --quick \
        --picture docs/figures/validation/CASE-model.png   # also a picture of the last state, deformed

CASE: hertz, stacked, arch, arch-friction, ironing or ironing-friction. The models are
tests/validation/_validation_models.py's (each names its source: repository and path); ``--quick``
runs a coarse version in seconds to a minute, the default the one docs/validation.md quotes.

* ``hertz``: MOOSE's sphere on sphere (modules/contact/test/tests/hertz_spherical/hertz_contact.i),
  force and contact radius against the input header's closed form; ``--quick`` cells of a/2, else a/5.
* ``stacked``: Zimmerman & Ateshian (2018) §3.5, four blocks pressed by half their height; per load
  step and interface the normal force N, the friction force T, the nodes in contact, sticking and
  slipping, and the slipping nodes' ``|t| / (mu p)``; ``--quick`` presses by a quarter, on coarser meshes.
* ``arch``, ``arch-friction``: Kratos' double arch (contact_structural_mechanics/validation/double_arch),
  the half-ring centre's vertical displacement per load step against the reference curve
  (tests/validation/data/); ``--quick`` the first 20 mm of the ends' travel; ``--quick`` and
  ``arch-friction`` on the coarser mesh (24 cells around the quarter ring, 1 across each layer,
  the base in cells of 5 mm). ``--e-base`` sets the base's Young's modulus (Kratos': 3e8 Pa), for
  docs/validation.md's study of the difference; the JSON's ``e_base`` records it.
* ``ironing``, ``ironing-friction``: Kratos' shallow ironing in 3D
  (contact_structural_mechanics/validation/shallow_ironing_3D, ProjectParameters_literature.json),
  frictionless and mu = 0.3: per load step the reference's ``time``, the reaction forces ``Fx`` and
  ``Fy`` on the indenter's driven top (as the reference plots them) and ``newton_iterations``, with
  ``wall`` the seconds since the start; ``--quick`` the press and the first 1 of the 10 mm slide.
  ``--h`` (the block's cells at the top, default 0.25), ``--slide-steps`` (default 40: 0.25 mm each),
  ``--law kratos`` (the source's coupled neo-Hookean, default) or ``contopt`` (contopt's decoupled one).

The JSON holds ``case``, ``quick``, ``seconds``, the case's results and, where the solve stopped
short, ``error`` (what was reached is kept).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "validation"))


def _solve(system, newton, rho=None, on_step=None):
    """``(state, error)``: a ConvergenceError is reported with the last converged state, not raised."""
    from contopt.errors import ConvergenceError
    from contopt.solve.static import solve_static

    try:
        return solve_static(system, rho, newton=newton, on_step=on_step), ""
    except ConvergenceError as err:
        return err.last_state, str(err).splitlines()[0]


def deformed_picture(system, state, path: Path, up: str | None = None, title: str = "", size=(900, 640)) -> Path:
    """A picture of ``state``: every body of ``system`` deformed (true scale), coloured by the contact
    pressure (contopt.io.render.render_deformed, from VTU files written beside ``path``)."""
    import tempfile

    from contopt.io.render import render_deformed
    from contopt.io.vtk import write_vtu

    model, disc = system.disc.model, system.disc
    offsets = [b.node_offset for b in disc.blocks]
    pressure = system.contact.pressure_fields(tuple(c.lam for c in state.contact), model.bodies, offsets)
    with tempfile.TemporaryDirectory() as tmp:
        files = [
            write_vtu(
                Path(tmp) / f"{body.name}.vtu",
                body.mesh.points,
                body.mesh.cells,
                {"displacement": disc.body_displacement(state.u, i), **pressure.get(body.name, {})},
            )
            for i, body in enumerate(model.bodies)
        ]
        return render_deformed(files, path, size=size, title=title, up=up)


def run_hertz(quick: bool, picture: Path | None = None) -> dict:
    from _validation_models import hertz_sphere_model, hertz_sphere_results

    from contopt.solve.newton import NewtonOptions
    from contopt.solve.static import AugmentationOptions, solve_static
    from contopt.solve.system import System

    h, ratio = (0.025, 1.6) if quick else (0.01, 1.4)
    model = hertz_sphere_model(h, ratio=ratio)
    system = System.of(model)
    state = solve_static(
        system,
        newton=NewtonOptions(n_steps=4, rtol=1e-10),
        augmentation=AugmentationOptions(pressure_rtol=1e-8, gap_rtol=1e-8),
    )
    res = hertz_sphere_results(system, state)
    if picture:
        deformed_picture(system, state, picture, title="MOOSE hertz_spherical: the quarter sphere on the plane")
    lam = np.asarray(state.contact[0].lam)
    block = system.contact.blocks[0]
    x = system.contact.X + state.u.reshape(-1, 3)
    r = np.linalg.norm(x[block.nodes, :2], axis=1)
    order = np.argsort(r)
    return res | {
        "h": h,
        "n_cells": model.body("sphere").mesh.n_cells,
        "profile_r": r[order].tolist(),
        "profile_p": lam[order].tolist(),
    }


def run_stacked(quick: bool, picture: Path | None = None) -> dict:
    from _validation_models import STACK_MU, stacked_blocks_model

    from contopt.solve.newton import NewtonOptions
    from contopt.solve.system import System

    press, cells, steps = (1.0, (3, 5, 3, 5), 5) if quick else (2.0, None, 10)
    model = stacked_blocks_model(press=press, cells=cells)
    system = System.of(model)
    top = system.disc.blocks[0].node_offset + model.body("block1").mesh.node_set("zmax")
    rows = []

    def record(state):
        row = {"t": float(state.t), "press": float(state.t) * press}
        row["top_force"] = float(-state.reactions.reshape(-1, 3)[top, 2].sum())
        for k, res in enumerate(state.contact):
            lam, a = np.asarray(res.lam), np.asarray(res.a)
            act = lam > 0
            traction = np.asarray(res.traction)
            stick = np.asarray(res.friction.stick) & act
            slip = act & ~stick
            ratio = np.linalg.norm(traction, axis=1)[slip] / (STACK_MU[k] * lam[slip]) if slip.any() else np.zeros(1)
            row[f"interface{k + 1}"] = {
                "N": float(lam @ a),
                "T": float(np.linalg.norm((traction * a[:, None]).sum(axis=0))),
                "T_abs": float(np.linalg.norm(traction, axis=1) @ a),
                "active": int(act.sum()),
                "stick": int(stick.sum()),
                "slip": int(slip.sum()),
                "slip_ratio_min": float(ratio.min()),
                "slip_ratio_max": float(ratio.max()),
            }
        rows.append(row)
        print(f"t = {row['t']:.3f}: top force {row['top_force']:.4g}", file=sys.stderr, flush=True)

    state, error = _solve(system, NewtonOptions(n_steps=steps), on_step=record)
    if picture:
        deformed_picture(system, state, picture, up="z", title=f"Stacked blocks pressed {state.t * press:.3g} mm")
    return {"press": press, "cells": cells, "mu": list(STACK_MU), "steps": rows, "error": error}


def run_arch(quick: bool, mu: float, e_base: float | None = None, picture: Path | None = None) -> dict:
    from _validation_models import ARCH_E_BASE, ARCH_TRAVEL, arch_centre_node, double_arch_model

    from contopt.solve.newton import NewtonOptions
    from contopt.solve.system import System

    travel = 0.02 if quick else ARCH_TRAVEL
    # the coarser mesh for --quick, and with friction (the default mesh's frictional run takes > 15 minutes here)
    coarse = quick or mu > 0
    sizes = {"n_theta": 24, "n_layer": 1, "h_base": 0.005} if coarse else {}
    e_base = ARCH_E_BASE if e_base is None else e_base
    model, rho = double_arch_model(mu=mu, travel=travel, e_base=e_base, **sizes)
    system = System.of(model)
    node = arch_centre_node(model)
    curve = [(0.0, 0.0)]

    def record(state):
        curve.append((float(state.t) * travel, float(state.u.reshape(-1, 3)[node, 1])))
        print(f"imposed {curve[-1][0]:.4g}: centre {curve[-1][1]:.4g}", file=sys.stderr, flush=True)

    steps = int(round(travel / 0.001))  # 1 mm per load step (Kratos: 0.2 mm)
    state, error = _solve(system, NewtonOptions(n_steps=steps), rho=rho, on_step=record)
    if picture:
        title = f"Double arch, mu = {mu:g}: the ends moved {1e3 * curve[-1][0]:.3g} mm"
        deformed_picture(system, state, picture, up="y", title=title)
    return {"mu": mu, "e_base": e_base, "travel": travel, "sizes": sizes, "curve": curve, "error": error}


def run_ironing(
    quick: bool,
    mu: float,
    h: float = 0.25,
    slide_steps: int = 40,
    law: str = "kratos",
    picture: Path | None = None,
) -> dict:
    from _validation_models import IRON_SLIDE, ironing_forces, ironing_model

    from contopt.solve.newton import NewtonOptions
    from contopt.solve.system import System

    slide = 1.0 if quick else IRON_SLIDE
    slide_steps = max(1, round(slide_steps * slide / IRON_SLIDE))
    press_steps = 8
    model, n_steps, time_of = ironing_model(
        mu=mu, h=h, press_steps=press_steps, slide_steps=slide_steps, slide=slide, kratos_law=law == "kratos"
    )
    system = System.of(model)
    rows = []
    t0 = time.perf_counter()

    def record(state):
        fx, fy = ironing_forces(system, state)
        row = {"time": time_of(float(state.t)), "Fx": fx, "Fy": fy}
        row |= {"newton_iterations": int(state.newton_iterations), "wall": round(time.perf_counter() - t0, 2)}
        rows.append(row)
        print(f"time {row['time']:.3f}: Fx {fx:.4g} Fy {fy:.4g} ({row['newton_iterations']} its)", file=sys.stderr)

    state, error = _solve(system, NewtonOptions(n_steps=n_steps), on_step=record)
    if picture:
        title = f"Shallow ironing, mu = {mu:g}, at t = {rows[-1]['time']:.3g}" if rows else ""
        deformed_picture(system, state, picture, up="y", title=title)
    cells = {b.name: b.mesh.n_cells for b in model.bodies}
    return {"mu": mu, "law": law, "h": h, "press_steps": press_steps, "slide_steps": slide_steps,
            "slide": slide, "cells": cells, "steps": rows, "error": error}  # fmt: skip


def reference_curve(name: str) -> np.ndarray:
    """(n, 2) a reference curve of tests/validation/data/ (comment lines start with #)."""
    lines = (ROOT / "tests" / "validation" / "data" / name).read_text().splitlines()
    return np.array([[float(v) for v in line.split(",")] for line in lines if line[:1].isdigit() or line[:1] == "-"])


#: the figures' titles
TITLES = {
    "hertz": "MOOSE hertz_spherical: sphere on sphere, cells of a/5",
    "stacked": "Stacked blocks (Zimmerman & Ateshian 2018): interfaces 1 and 2 coincide",
    "arch": "Kratos double arch, frictionless",
    "arch-friction": "Kratos double arch, mu = 0.5",
    "ironing": "Kratos shallow ironing 3D, frictionless",
    "ironing-friction": "Kratos shallow ironing 3D, mu = 0.3",
}


def plot(data: dict, figure: Path) -> Path:
    """The case's figure against its reference, contopt.io.plots' style (Agg, written atomically)."""
    from contopt.io.plots import _pyplot, _save

    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6.0, 4.2))
    case = data["case"]
    if case == "hertz":
        r, p = np.asarray(data["profile_r"]), np.asarray(data["profile_p"])
        a, p0 = data["a_closed"], data["p0_closed"]
        rr = np.linspace(0, a, 200)
        ax.plot(rr, p0 * np.sqrt(1 - (rr / a) ** 2), "k-", label=f"Hertz for F = {data['force']:.0f}")
        ax.plot(r, p, "o", ms=3, label="contopt, nodal pressures")
        ax.set_xlabel("distance from the axis r")
        ax.set_ylabel("contact pressure")
        ax.set_xlim(0, 2.5 * a)
    elif case == "stacked":
        steps = data["steps"]
        x = [s["press"] for s in steps]
        for k, mu in enumerate(data["mu"]):
            key = f"interface{k + 1}"
            ratio = [s[key]["T_abs"] / max(s[key]["N"], 1e-300) for s in steps]
            ax.plot(x, ratio, "o-", label=f"interface {k + 1}: ∫|t| / N")
            ax.axhline(mu, color=f"C{k}", ls=":", lw=1)
        ax.set_xlabel("top's travel (mm)")
        ax.set_ylabel("friction over normal force (dotted: mu)")
        ax.set_yscale("log")
    elif case.startswith("ironing"):
        from _validation_models import ironing_reference

        ref = ironing_reference(data["mu"])
        steps = data["steps"]
        t = [0.0, 0.2] + [s["time"] for s in steps]
        for key, colour in (("Fy", "C0"), ("Fx", "C3")):
            ax.plot(ref[key][:, 0], ref[key][:, 1], "o", mfc="none", color=colour, label=f"{key} reference (read off)")
            ax.plot(t, [0.0, 0.0] + [s[key] for s in steps], "x-", ms=4, color=colour, label=f"{key} contopt")
        ax.set_xlabel("time (s): pressed 0.2-1, slid 10 mm 1-2")
        ax.set_ylabel("reaction on the indenter (N)")
    else:
        name = "double_arch_reference.csv" if data["mu"] == 0 else "double_arch_frictional_reference.csv"
        ref = reference_curve(name)
        source = "Kratos' table" if data["mu"] == 0 else "read off Kratos' figure"
        ax.plot(1e3 * ref[:, 0], 1e3 * ref[:, 1], "o-", mfc="none", label=f"reference ({source})")
        c = np.asarray(data["curve"])
        e_base = data.get("e_base", 3e8)
        ax.plot(
            1e3 * c[:, 0],
            1e3 * c[:, 1],
            "x-",
            label="contopt" + (f", base E = {e_base:.3g} Pa" if e_base != 3e8 else ""),
        )
        ax.set_xlabel("ends' imposed displacement (mm)")
        ax.set_ylabel("centre's vertical displacement (mm)")
    ax.grid(alpha=0.3)
    ax.legend()
    ax.set_title(TITLES[case])
    fig.tight_layout()
    return _save(plt, fig, figure)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", choices=("hertz", "stacked", "arch", "arch-friction", "ironing", "ironing-friction"))
    parser.add_argument("--out", type=Path, help="the JSON to write")
    parser.add_argument("--quick", action="store_true", help="a coarse version in seconds to a minute")
    parser.add_argument("--e-base", type=float, help="arch: the base's Young's modulus (default Kratos' 3e8 Pa)")
    parser.add_argument("--h", type=float, default=0.25, help="ironing: the block's cells at its top")
    parser.add_argument("--slide-steps", type=int, default=40, help="ironing: load steps over the 10 mm slide")
    parser.add_argument("--law", choices=("kratos", "contopt"), default="kratos", help="ironing: the neo-Hookean")
    parser.add_argument("--plot", type=Path, help="a JSON this script wrote: draw its figure")
    parser.add_argument("--figure", type=Path, help="the PNG --plot writes")
    parser.add_argument(
        "--picture", type=Path, help="with --case: a PNG of the last state, deformed (needs the viz extra)"
    )
    args = parser.parse_args(argv)
    if args.plot:
        if not args.figure:
            parser.error("--plot needs --figure PNG")
        plot(json.loads(args.plot.read_text()), args.figure)
        return 0
    if not (args.case and args.out):
        parser.error("give --case and --out (or --plot JSON --figure PNG)")
    from contopt.config import setup_jax

    setup_jax()
    t0 = time.perf_counter()
    if args.case == "hertz":
        data = run_hertz(args.quick, args.picture)
    elif args.case == "stacked":
        data = run_stacked(args.quick, args.picture)
    elif args.case.startswith("ironing"):
        mu = 0.3 if args.case == "ironing-friction" else 0.0
        data = run_ironing(args.quick, mu, args.h, args.slide_steps, args.law, args.picture)
    else:
        data = run_arch(args.quick, 0.5 if args.case == "arch-friction" else 0.0, args.e_base, args.picture)
    data = {"case": args.case, "quick": args.quick, "seconds": round(time.perf_counter() - t0, 1)} | data
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(data, indent=1))
    stopped = f" (stopped: {data['error']})" if data.get("error") else ""
    print(f"{args.case}: {data['seconds']} s -> {args.out}{stopped}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
