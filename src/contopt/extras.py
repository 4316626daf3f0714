"""The optional parts of contopt: which extra of ``pip install 'contopt[...]'`` brings what, whether
it is installed here, and the one line that says how to get it.

The core (numpy, scipy, JAX, meshio, scikit-image, rich) analyses, optimizes with MMA, solves with
SciPy's SuperLU and writes VTU, CSV, JSON and STL. The extras add:

``pardiso``  MKL Pardiso through pypardiso, the fastest direct solver (MKL: x86-64 only)
``cholmod``  SuiteSparse CHOLMOD through scikit-sparse (built against the system's SuiteSparse)
``petsc``    the iterative solver, CG + AMG (PETSc's wheel, Python 3.12+)
``ipopt``    the IPOPT optimizer through cyipopt (built against the system's Ipopt)
``viz``      the pictures (PNG, matplotlib and PyVista/VTK) and ``report.html``
``cad``      meshing CAD files (STEP, IGES, BREP, STL) with Gmsh: ``mesh = { cad = ... }``, ``contopt mesh``

``CONTOPT_WITHOUT=pardiso,viz`` (comma-separated names of extras) makes contopt act as if those
were not installed, e.g. the no-MKL path of an aarch64 or macOS machine tried on one with MKL.
Nothing here imports the packages it asks about.
"""

from __future__ import annotations

import importlib.util
import os

from contopt.errors import ContoptError

#: extra -> the modules it provides (all must import)
EXTRAS: dict[str, tuple[str, ...]] = {
    "pardiso": ("pypardiso",),
    "cholmod": ("sksparse",),
    "petsc": ("petsc4py",),
    "ipopt": ("cyipopt",),
    "viz": ("matplotlib", "pyvista", "vtkmodules"),
    "cad": ("gmsh",),
}
#: what installing an extra needs beyond pip, said with its install line
_NEEDS = {
    "pardiso": " (MKL: x86-64 Linux and Windows)",
    "cholmod": " (it compiles against SuiteSparse: apt-get install libsuitesparse-dev)",
    "petsc": " (Python 3.12+; then python -m contopt.solve.linear.petsc_install)",
    "ipopt": " (it compiles against Ipopt: apt-get install coinor-libipopt-dev pkg-config; or conda-forge's cyipopt)",
    "viz": "",
    "cad": " (Gmsh's wheel; its library needs X and GL: apt-get install libglu1-mesa libxcursor1 libxft2 libxinerama1)",
}
#: the environment variable of extras to act as not installed
WITHOUT_ENV = "CONTOPT_WITHOUT"


class MissingExtra(ContoptError, ImportError):
    """Something needs an extra that is not installed (the message says which and how to install it)."""


def hidden() -> frozenset[str]:
    """The extras ``$CONTOPT_WITHOUT`` names; a name that is no extra is a one-line error."""
    names = frozenset(n.strip() for n in os.environ.get(WITHOUT_ENV, "").split(",") if n.strip())
    unknown = sorted(names - set(EXTRAS))
    if unknown:
        raise MissingExtra(
            f"{WITHOUT_ENV} names {', '.join(unknown)}, which is no extra; use some of {', '.join(EXTRAS)}"
        )
    return names


def installed(extra: str) -> bool:
    """Whether ``extra``'s modules can be imported here (and ``$CONTOPT_WITHOUT`` does not hide it)."""
    if extra in hidden():
        return False
    return all(_findable(module) for module in EXTRAS[extra])


def _findable(module: str) -> bool:
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):  # a broken install counts as none
        return False


def install_hint(extra: str) -> str:
    """How to install ``extra``: ``pip install 'contopt[viz]'`` and what it needs beyond pip."""
    return f"pip install 'contopt[{extra}]'{_NEEDS[extra]}"


def missing(extra: str, who_needs: str) -> str:
    """One line: ``who_needs`` (e.g. "the pictures need") ``extra``, not installed here, and how to install it."""
    why = f"hidden by {WITHOUT_ENV}" if extra in hidden() else "not installed"
    return f"{who_needs} the {extra} extra ({why}): {install_hint(extra)}"


def require(extra: str, who_needs: str) -> None:
    """Raise :class:`MissingExtra` saying :func:`missing` unless ``extra`` is installed."""
    if not installed(extra):
        raise MissingExtra(missing(extra, who_needs))
