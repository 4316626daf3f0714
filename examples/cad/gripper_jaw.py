"""Write gripper-jaw.step, the CAD of the bundled case gripper-jaw (src/contopt/cases/files/), with
Gmsh's OpenCASCADE kernel: a jaw 2 x 1 x 1 (x, y, z) with a cylindrical groove of radius 0.4 along y
in its top face (axis at x = 1, z = 1.25: 0.15 deep), where a rigid cylinder grips.

    python examples/cad/gripper_jaw.py [OUT]     # default: src/contopt/cases/files/gripper-jaw.step

It prints the solid's surfaces as `contopt mesh` names them (Gmsh's tags): the problem file names the
bottom (z = 0, supported) and the groove (in contact) by them.
"""

import sys
from pathlib import Path

import gmsh

from contopt.mesh.cad import cad_surfaces

ROOT = Path(__file__).resolve().parents[2]
out = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "src" / "contopt" / "cases" / "files" / "gripper-jaw.step"

gmsh.initialize(readConfigFiles=False, interruptible=False)
gmsh.option.setNumber("General.Terminal", 0)
jaw = gmsh.model.occ.addBox(0.0, 0.0, 0.0, 2.0, 1.0, 1.0)
groove = gmsh.model.occ.addCylinder(1.0, -0.1, 1.25, 0.0, 1.2, 0.0, 0.4)  # axis along y, longer than the jaw
gmsh.model.occ.cut([(3, jaw)], [(3, groove)])
gmsh.model.occ.synchronize()
gmsh.write(str(out))
gmsh.finalize()

for s in cad_surfaces(out):
    print(f"{s.name:12s} area {s.area:.4f}")
