"""``contopt info``."""

from __future__ import annotations

from contopt import __version__


def cmd_info(args) -> int:
    """``contopt info``: the version, every linear-solver backend with whether it is there and why not, and
    the other extras (IPOPT, the pictures) with how to install them."""
    # here, not atop: the command line imports this module for every command (`contopt --help` stays light)
    from contopt.solve.linear import BACKENDS, LinearSolverOptions, available_backends, why_unavailable
    from contopt.solve.linear.options import ITERATIVE

    print(f"contopt {__version__}")
    avail = available_backends()
    print("sparse solvers available (preferred first):", ", ".join(avail))
    for name in BACKENDS:
        kind = "iterative" if name in ITERATIVE else "direct"
        if name in avail:
            detail = ""
            if name == "petsc":
                from contopt.solve.linear import petsc

                detail = f": {petsc.describe()}"
            print(f"  {name:8s} {kind}, available{detail}")
        else:
            print(f"  {name:8s} {kind}, not available: {why_unavailable(name)}")
    defaults = LinearSolverOptions()
    auto = "petsc" if "petsc" in avail else "none installed"
    print(
        f"--solver auto: a direct solver below {defaults.iterative_above:,} free dofs, from there the iterative one "
        f"({auto}); with contact from {defaults.trial_above:,} on, whichever of the two its first matrices measure "
        "as faster while a direct factor fits in memory"
    )
    from contopt import extras

    for extra, what in (("ipopt", "the IPOPT optimizer (--optimizer ipopt)"), ("viz", "pictures and report.html")):
        print(f"{what}: " + ("installed" if extras.installed(extra) else extras.missing(extra, "need")))
    return 0
