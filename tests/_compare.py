"""``problem_differences``: what differs between two design problems (tests of the problem files).

Used where a problem file is checked against a problem built another way: the tutorial's Python
script against its TOML file, a case file against its edited copy, a run directory's copy of the
problem against the file that was run.
"""

import dataclasses

import numpy as np


def _response_key(r) -> tuple:
    """What defines a response: its class, name, selections and (for combinations) parts and rule."""
    combine = getattr(r, "combine", None)
    rule = getattr(combine, "__qualname__", None) or repr(combine)
    return (
        type(r).__name__,
        r.name,
        getattr(r, "bodies", None),
        getattr(r, "interfaces", None),
        getattr(r, "quadrature", None),
        rule if combine is not None else None,
        tuple(_response_key(p) for p in getattr(r, "parts", ())),
    )


def _model_of(model):
    """The Model of a Model, Discretization or System."""
    from contopt.assembly.system import Discretization
    from contopt.solve.system import System

    if isinstance(model, System):
        return model.model
    return model.model if isinstance(model, Discretization) else model


def problem_differences(a, b) -> list[str]:
    """What differs between two design problems (an empty list: the same problem).

    Compares the models (body names, mesh points and cells, materials, F-bar, supports with their
    values and node sets, loads, contact interfaces with their facet sets), the designs (maps, each
    designed body's settings, and the design matrices G built on the mesh with their summaries),
    the objective and constraints (class, name, selections), normalization and solver options.
    Supports whose value is a callable are compared by identity (a LoadPath by its points). E.g. a
    problem file against the Python script it mirrors: ``problem_differences(load_spec(path).problem, builder())``.
    """
    from contopt.assembly.system import discretize

    out = []

    def same(what, x, y):
        try:
            if callable(x) or callable(y):  # a LoadPath by its points, a RigidMotion by its fields, others by identity
                by_value = hasattr(x, "points") or dataclasses.is_dataclass(x)
                equal = x == y if type(x) is type(y) and by_value else x is y
            else:
                equal = bool(np.array_equal(np.asarray(x), np.asarray(y)))
        except (TypeError, ValueError):
            equal = x == y
        if not equal:
            out.append(f"{what}: {x!r} != {y!r}" if len(repr(x)) + len(repr(y)) < 300 else f"{what} differ")
        return equal

    ma, mb = (_model_of(p.model) for p in (a, b))
    if not same("bodies", [x.name for x in ma.bodies], [x.name for x in mb.bodies]):
        return out
    for x, y in zip(ma.bodies, mb.bodies):
        if same(
            f"bodies[{x.name}] mesh shape",
            (x.mesh.points.shape, x.mesh.cells.shape),
            (y.mesh.points.shape, y.mesh.cells.shape),
        ):
            same(f"bodies[{x.name}] mesh points", x.mesh.points, y.mesh.points)
            same(f"bodies[{x.name}] mesh cells", x.mesh.cells, y.mesh.cells)
        same(f"bodies[{x.name}] material", dataclasses.astuple(x.material), dataclasses.astuple(y.material))
        same(f"bodies[{x.name}] fbar", x.fbar, y.fbar)
    if same("number of supports", len(ma.dirichlet), len(mb.dirichlet)):
        for i, (x, y) in enumerate(zip(ma.dirichlet, mb.dirichlet)):
            if same(f"supports[{i}]", (x.body, x.node_set, x.components), (y.body, y.node_set, y.components)):
                same(
                    f"supports[{i}] value",
                    x.value if callable(x.value) else np.atleast_1d(x.value),
                    y.value if callable(y.value) else np.atleast_1d(y.value),
                )
                same(
                    f"supports[{i}] nodes",
                    ma.body(x.body).mesh.node_set(x.node_set),
                    mb.body(y.body).mesh.node_set(y.node_set),
                )
    if same("number of loads", len(ma.loads), len(mb.loads)):
        for i, (x, y) in enumerate(zip(ma.loads, mb.loads)):
            if same(
                f"loads[{i}]", (type(x).__name__, *dataclasses.astuple(x)), (type(y).__name__, *dataclasses.astuple(y))
            ):
                if hasattr(x, "facet_set"):
                    same(
                        f"loads[{i}] facets",
                        ma.body(x.body).mesh.facet_set(x.facet_set),
                        mb.body(y.body).mesh.facet_set(y.facet_set),
                    )
    sa_, sb_ = getattr(ma, "soft_supports", ()), getattr(mb, "soft_supports", ())
    if same("soft supports", [x.body for x in sa_], [x.body for x in sb_]):
        same(
            "soft support stiffness",
            np.allclose([x.stiffness for x in sa_], [x.stiffness for x in sb_], rtol=1e-12, atol=0),
            True,
        )
    if same("number of contact interfaces", len(ma.interfaces), len(mb.interfaces)):
        for i, (x, y) in enumerate(zip(ma.interfaces, mb.interfaces)):
            if same(f"contact[{i}]", dataclasses.astuple(x), dataclasses.astuple(y)):
                for side in ("nonmortar", "mortar"):
                    (bx, sx), (by, sy) = getattr(x, side), getattr(y, side)
                    same(f"contact[{i}].{side} facets", ma.body(bx).mesh.facet_set(sx), mb.body(by).mesh.facet_set(sy))
    da, db = a.design, b.design
    same("design maps", (da.heaviside, da.simp), (db.heaviside, db.simp))
    if same("designed bodies", [x.body for x in da.bodies], [x.body for x in db.bodies]):
        for x, y in zip(da.bodies, db.bodies):
            for key in ("parameterization", "volume_fraction", "symmetry", "skins", "skin_eps"):
                same(f"design of {x.body}: {key}", repr(getattr(x, key)), repr(getattr(y, key)))
        if not out:
            sa, sb = da.build(discretize(ma)), db.build(discretize(mb))
            same("design summary", sa.summary(), sb.summary())
            for pa, pb in zip(sa.parts, sb.parts):
                if same(f"design of {pa.spec.body}: G shape", pa.G.shape, pb.G.shape):
                    diff = abs(pa.G - pb.G)
                    if diff.nnz and diff.max() > 0:
                        out.append(f"design of {pa.spec.body}: G differs by up to {diff.max():.3g}")
                same(f"design of {pa.spec.body}: fixed cells", pa.fixed, pb.fixed)
                if pa.skin is not None or pb.skin is not None:
                    same(f"design of {pa.spec.body}: skin", pa.skin, pb.skin)
    same("objective", _response_key(a.objective), _response_key(b.objective))
    same(
        "constraints",
        [(_response_key(c.response), c.upper, c.lower, c.scale) for c in a.constraints],
        [(_response_key(c.response), c.upper, c.lower, c.scale) for c in b.constraints],
    )
    for key in ("normalize", "newton", "linear", "augmentation", "adjoint", "warm_start", "case_workers"):
        same(key, repr(getattr(a, key)), repr(getattr(b, key)))
    return out
