"""Tutorial: the stiffest bridge under a rigid roller (docs/tutorial.md).

A beam spans two narrow support pads; a stiff roller lying across its top is pressed 0.04 into it.
Which 30 % of the beam's material carries the roller best, i.e. makes the contact force largest?

Axes: the beam spans x, y points up, z runs along the roller's axis (the O-grid cylinder
generator makes cylinders along z). The same problem as a problem file is examples/tutorial.toml.

    python examples/tutorial.py                # optimize, results in results/tutorial
    python examples/tutorial.py --max-iter 5   # fewer iterations
    python examples/tutorial.py --overwrite    # replace an earlier run (refused without, as the CLI does)
"""

from __future__ import annotations

import argparse

from contopt import (
    Body,
    ContactForce,
    ContactInterface,
    Density,
    Design,
    DesignedBody,
    DesignProblem,
    Dirichlet,
    Heaviside,
    MMAOptions,
    Model,
    NewtonOptions,
    Simp,
    box,
    cylinder,
    neo_hookean,
    optimize_design,
    setup_jax,
)

SPAN, HEIGHT, DEPTH = 2.0, 0.5, 0.5
ROLLER_RADIUS = 0.2
INDENTATION = 0.04


def bridge_model() -> Model:
    """The beam on its pads and the roller above its middle."""
    beam = box(lengths=(SPAN, HEIGHT, DEPTH), divisions=(16, 4, 4))  # sets xmin, ..., ymin (bottom), ymax (top)
    # the support pads: the bottom facets whose centre lies within 0.2 of an end (two cells long each)
    bottom = beam.facet_set("ymin")  # (k, 2) rows (cell, local face)
    x = beam.points[beam.facet_nodes(bottom)].mean(axis=1)[:, 0]  # (k,) facet centres' x
    beam = beam.with_sets(facet_sets={"left_pad": bottom[x <= 0.2], "right_pad": bottom[x >= SPAN - 0.2]})
    # the roller: its axis along z, 0.1 longer than the beam is deep at each end, resting on the beam's top;
    # a 64-gon (16 core cells a side), nodes 0.02 apart: finer than the contact zone (half-width ~0.03)
    roller = cylinder(
        radius=ROLLER_RADIUS,
        length=DEPTH + 0.2,
        divisions=(16, 1, 4),
        center=(SPAN / 2, HEIGHT + ROLLER_RADIUS, DEPTH / 2),
    )
    return Model(
        bodies=(Body("beam", beam, neo_hookean(E=1.0, nu=0.3)), Body("roller", roller, neo_hookean(E=100.0, nu=0.3))),
        dirichlet=(
            Dirichlet("beam", "left_pad", "xyz", 0.0),  # a pin
            Dirichlet("beam", "right_pad", "yz", 0.0),  # a roller support: free to slide along x
            Dirichlet("roller", "all", "xyz", (0.0, -INDENTATION, 0.0)),
        ),  # the roller moves as a rigid body
        # the two surfaces: contopt makes the finer one, the roller's mantle, the nonmortar side (it carries
        # the contact pressure). Penalty enforcement: one Newton solve per analysis (the augmented
        # Lagrangian, "alm", converges the constraint exactly at the price of a few more solves)
        interfaces=(ContactInterface(surfaces=(("beam", "ymax"), ("roller", "outer")), law="penalty"),),
    )


def bridge_problem() -> DesignProblem:
    """Maximize the contact force with at most 30 % of the beam's volume."""
    design = Design(
        bodies=(DesignedBody("beam", Density(radius=0.2), volume_fraction=0.3),),
        heaviside=Heaviside(eta=10.0),
        simp=Simp(p=3.0, nu0=0.01),
    )
    return DesignProblem(
        model=bridge_model(),
        design=design,
        objective=-ContactForce(interfaces=("beam-roller",)),  # minimized: so the contact force is maximized
        normalize="full",  # divided by its value for the full beam
        newton=NewtonOptions(n_steps=2),
    )


def main(argv=None) -> None:
    setup_jax()  # float64 and the compilation cache: first, before any analysis
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--max-iter", type=int, default=40)
    parser.add_argument("--out", default="results/tutorial")
    parser.add_argument("--overwrite", action="store_true", help="replace an earlier run in --out (as the CLI)")
    parser.add_argument("--resume", action="store_true", help="continue an interrupted run in --out")
    args = parser.parse_args(argv)
    result = optimize_design(
        bridge_problem(),
        "mma",
        MMAOptions(max_iter=args.max_iter, move=0.1, asyinit=0.1),
        out=args.out,
        overwrite=args.overwrite,
        resume=args.resume,
        progress=lambda row, eta: print(
            f"it {row['iteration']:3d}  f {row['objective']:.5f}  volume {row['volume_fractions']['beam']:.3f}"
        ),
    )
    print(
        f"{result.status} after {result.iterations} iterations: contact force {-result.objective:.4g} "
        f"({-result.normalized_objective:.3f} of the full beam's), volume fraction "
        f"{result.volume_fractions[0]:.3f}; open {args.out}/design.pvd in ParaView"
    )


if __name__ == "__main__":
    main()
