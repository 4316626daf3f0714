"""The built-in responses as problem files and the command line name them: what each is and which
options it takes, declared apart from their JAX integrands (:mod:`contopt.responses.functionals`,
whose ``BUILTIN`` maps these names to the classes; ``tests/responses/test_catalog.py`` checks that
every class takes exactly the options listed here), so that reading about them loads no JAX.
"""

from __future__ import annotations

from dataclasses import dataclass

#: how a contact integrand is integrated (:class:`contopt.responses.functionals.Functional`)
QUADRATURES = ("overlap", "gauss", "nodal")

#: what a load-path response reads at each load step (:mod:`contopt.responses.path`)
ON = ("contact", "reaction", "displacement", "energy")

#: the options each ``on`` reads, besides ``steps`` and the combination's own (the others are refused)
READS = {
    "contact": ("interfaces", "quadrature", "direction"),
    "reaction": ("bodies", "set", "direction"),
    "displacement": ("bodies", "set", "direction"),
    "energy": ("bodies",),
}

#: how the stress aggregates its cells (:class:`contopt.responses.stress.Stress`; its AGGREGATES)
AGGREGATES = ("pnorm", "ks")


@dataclass(frozen=True)
class Option:
    """One option of a response: what it means, the value it takes and its unit ("" if none)."""

    doc: str
    type: str
    unit: str = ""
    choices: tuple = ()
    table: str = ""  # the key table a table-valued option follows (problem-file schema)


#: every option a built-in response takes (one word per thing: an option means the same in each)
OPTIONS = {
    "name": Option("the response's name in the history, the plots and messages (default: its own)", "string"),
    "bodies": Option(
        "the bodies it integrates over, by name (default: all); a load-path response on a reaction or a "
        "displacement: the one body whose support, motion or node set it reads",
        "names",
    ),
    "interfaces": Option("the [[contact]] interfaces it integrates over, by name (default: all)", "names"),
    "quadrature": Option(
        "how the pressure is integrated: over the mortar overlap (the force exchanged), over whole "
        "nonmortar facets with 2x2 Gauss points (the paper's appendix A; tet10: the curved tri6 faces) "
        "or over whole nodal areas",
        "string",
        choices=QUADRATURES,
    ),
    "direction": Option(
        'the direction [x, y, z] the force is measured along; contact-force also takes "norm" (the '
        "resultant's size) and then measures the interface's resultant force instead of the pressure integral; "
        "a load-path response on a reaction (default: along the motion) or a displacement: the direction read",
        "direction",
    ),
    "normalized": Option("divide the variance by the squared mean pressure (dimensionless)", "boolean"),
    "target": Option(
        "the wanted force-displacement curve: points [load factor, force] with the load factors increasing "
        "within [0, 1], interpolated linearly (a prescribed motion at load factor t has moved t times its value)",
        "rows",
        "force",
    ),
    "steps": Option(
        "the load steps the force is read at: a count n (t_k = k / n, k = 1 .. n) or a list of load factors "
        "t_k increasing within (0, 1], e.g. the steps after a tool touches (the analysis ends a step on each)",
        "steps",
    ),
    "sharpness": Option(
        "the s of a smooth maximum or minimum (1/s) log(sum_k w_k exp(s v_k)) of the values v_k it aggregates "
        "(weights w_k summing to 1): within log(1/w_k) / s of the extreme (log(steps) / s over load steps), in "
        "1/(the unit of the values)",
        "number",
        "1/(the unit of the values)",
    ),
    "aggregate": Option(
        'how the cells\' stresses are aggregated: "pnorm" (the volume-weighted p-norm, exponent p) or "ks" (the '
        "volume-weighted lower-bound Kreisselmeier-Steinhauser function, sharpness s)",
        "string",
        choices=AGGREGATES,
    ),
    "on": Option(
        "what a load-path response reads at each load step: the contact force, the reaction of a body's "
        "support or prescribed motion, the mean displacement of a node set, or the strain energy (default contact)",
        "string",
        choices=ON,
    ),
    "set": Option("the node set (or facet set) of the body a reaction or a displacement is read on", "string"),
    "p": Option(
        "the exponent of the volume-weighted p-norm the cells' stresses are aggregated by, >= 2 (default 8): "
        "larger is closer to the peak and less smooth",
        "number",
    ),
    "q": Option(
        "the relaxation rho^q of each cell's von Mises stress by its stiffness factor rho, in [0, 1] "
        "(default 0.5; 0: the solid material's stress, 1: the ersatz material's)",
        "number",
    ),
    "region": Option(
        "the cells it aggregates over: those whose reference centre lies in a box {lower, upper}, in a closed "
        "surface (a file name) or in one of a list of them (default: every cell of the bodies)",
        "regions",
        "length",
        table="design.bodies.solid",
    ),
}


@dataclass(frozen=True)
class ResponseKind:
    """A built-in response: one line on what it is, its options in its constructor's order, the unit
    of its value, and the options it cannot do without."""

    doc: str
    options: tuple[str, ...]
    unit: str = ""
    required: tuple[str, ...] = ()


#: the built-in responses by name (:data:`contopt.responses.functionals.BUILTIN` has their classes)
RESPONSES = {
    "strain-energy": ResponseKind("the stored energy ∫ W dV of the bodies", ("bodies",), "energy"),
    "compliance": ResponseKind("the work t f_ext . u of the body forces and tractions", ("bodies",), "energy"),
    "contact-force": ResponseKind(
        "the normal force the bodies exchange, ∫ lam da where they touch",
        ("interfaces", "quadrature", "direction"),
        "force",
    ),
    "friction-force": ResponseKind(
        "the friction force the nonmortar body exerts on the mortar body along direction",
        ("direction", "interfaces"),
        "force",
        required=("direction",),
    ),
    "pressure-variance": ResponseKind(
        "the area-weighted variance of the contact pressures over the nodes in contact",
        ("interfaces", "normalized"),
        "pressure^2 (dimensionless if normalized)",
    ),
    "volume-fraction": ResponseKind("the share of the bodies' volume that is material", ("bodies",)),
    "stress": ResponseKind(
        "the volume-weighted p-norm (sum_e V_e (rho_e^q s_e)^p / sum_e V_e)^(1/p), or KS function "
        "(1/s) log(sum_e V_e exp(s rho_e^q s_e) / sum_e V_e), of the relaxed von Mises stress of the bodies' "
        "cells (a smooth lower bound of its peak)",
        ("bodies", "p", "q", "region", "aggregate", "sharpness"),
        "stress (force/area)",
    ),
    "force-target": ResponseKind(
        "the mean squared miss (1/steps) sum_k (F_k - F*(t_k))^2 of the contact force F_k (as contact-force "
        "measures it; or what on reads) at the load steps t_k from the target curve F*",
        ("target", "steps", "interfaces", "quadrature", "direction", "on", "bodies", "set"),
        "force^2",
        required=("target", "steps"),
    ),
    "force-max": ResponseKind(
        "the largest contact force (or what on reads) over the load steps t_k, aggregated smoothly: "
        "(1/s) log((1/n) sum_k exp(s F_k))",
        ("steps", "sharpness", "interfaces", "quadrature", "direction", "on", "bodies", "set"),
        "force",
        required=("steps", "sharpness"),
    ),
    "force-min": ResponseKind(
        "the smallest contact force (or what on reads) over the load steps t_k, aggregated smoothly: "
        "-(1/s) log((1/n) sum_k exp(-s F_k))",
        ("steps", "sharpness", "interfaces", "quadrature", "direction", "on", "bodies", "set"),
        "force",
        required=("steps", "sharpness"),
    ),
}
