"""contopt: topology optimization of hyperelastic bodies in contact.

The public API: everything a problem needs, importable from ``contopt`` itself::

    import contopt as co

    beam = co.box((2.0, 0.5, 0.5), (16, 4, 4))
    model = co.Model(bodies=(co.Body("beam", beam, co.neo_hookean(1.0, 0.3)), ...),
                     interfaces=(co.ContactInterface(("beam", "ymax"), ("roller", "outer"), law=co.Penalty()),))
    state = co.solve_static(model)

Names are imported on first use, so ``import contopt`` is fast and loads no JAX. Nothing here
changes global JAX state on import; entry points call :func:`contopt.config.enable_x64` (and
the CLI/tests enable the persistent compilation cache) explicitly. The modules below stay the
place to look for everything else (options of the solvers, lower-level pieces).
"""

from importlib import import_module

#: public name -> module that defines it
_PUBLIC = {
    # meshes
    "Mesh": "contopt.mesh.core",
    "box": "contopt.mesh.generators",
    "cylinder": "contopt.mesh.generators",
    "annulus": "contopt.mesh.generators",
    "cylinder_shell_sector": "contopt.mesh.generators",
    "read_mesh": "contopt.mesh.io",
    "read_bodies": "contopt.mesh.io",
    "write_mesh": "contopt.mesh.io",
    # materials
    "Material": "contopt.material.hyperelastic",
    "MooneyRivlin": "contopt.material.hyperelastic",
    "neo_hookean": "contopt.material.hyperelastic",
    # the model
    "Body": "contopt.assembly.model",
    "Model": "contopt.assembly.model",
    "Dirichlet": "contopt.assembly.model",
    "Traction": "contopt.assembly.model",
    "BodyForce": "contopt.assembly.model",
    "Acceleration": "contopt.assembly.model",
    "SoftSupport": "contopt.assembly.model",
    # contact
    "ContactInterface": "contopt.contact.interface",
    "Penalty": "contopt.contact.laws",
    "AugmentedLagrangian": "contopt.contact.laws",
    "AugmentationOptions": "contopt.contact.laws",
    "PenetrationCheck": "contopt.contact.verify",
    # analysis
    "System": "contopt.solve.system",
    "State": "contopt.solve.static",
    "solve_static": "contopt.solve.static",
    "NewtonOptions": "contopt.solve.newton",
    "LinearSolverOptions": "contopt.solve.linear",
    # responses and sensitivities
    "StrainEnergy": "contopt.responses.functionals",
    "Compliance": "contopt.responses.functionals",
    "ContactForce": "contopt.responses.functionals",
    "PressureVariance": "contopt.responses.functionals",
    "VolumeFraction": "contopt.responses.functionals",
    "Functional": "contopt.responses.functionals",
    "Combination": "contopt.responses.base",
    "Response": "contopt.responses.base",
    "sensitivities": "contopt.adjoint.sensitivity",
    "AdjointOptions": "contopt.adjoint.sensitivity",
    "check_gradient": "contopt.adjoint.check",
    # designs
    "Design": "contopt.design.space",
    "DesignedBody": "contopt.design.space",
    "Density": "contopt.design.space",
    "BSplineGrid": "contopt.design.bspline",
    "Heaviside": "contopt.design.maps",
    "Robust": "contopt.design.maps",
    "Simp": "contopt.design.maps",
    "CyclicSymmetry": "contopt.design.symmetry",
    "BoxRegion": "contopt.design.space",
    "RadialSkin": "contopt.design.space",
    # optimization
    "DesignProblem": "contopt.optimize.problem",
    "Constraint": "contopt.optimize.problem",
    "LoadCase": "contopt.optimize.load_case",
    "optimize_design": "contopt.optimize.driver",
    "MMAOptions": "contopt.optimize.mma",
    "IpoptOptions": "contopt.optimize.ipopt",
    # problem files; set-up
    "load_spec": "contopt.cases.spec",
    "setup_jax": "contopt.config",
    # errors
    "ContoptError": "contopt.errors",
    "ConfigError": "contopt.errors",
    "MeshError": "contopt.errors",
    "ConvergenceError": "contopt.errors",
}

__all__ = ["__version__", *sorted(_PUBLIC)]


#: public names that differ from their definition's (``contopt.optimize`` is the subpackage)
_RENAMED = {"optimize_design": "optimize"}


def _version() -> str:
    """The installed distribution's version: pyproject.toml's ``version``, the one place it is written."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("contopt")
    except PackageNotFoundError:  # a source tree on sys.path that was never installed
        return "0+unknown"


def __getattr__(name: str):
    if name == "__version__":
        globals()[name] = value = _version()
        return value
    if name in _PUBLIC:
        value = getattr(import_module(_PUBLIC[name]), _RENAMED.get(name, name))
        globals()[name] = value  # the next access is a plain attribute
        return value
    raise AttributeError(f"module 'contopt' has no attribute {name!r}")


def __dir__():
    return __all__
