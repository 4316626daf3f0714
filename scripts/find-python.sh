#!/usr/bin/env bash
# Print the Python the project's venv is made with: the first of python3, python3.13, python3.12
# and pyenv's 3.12+ builds that is 3.12 or newer (the PETSc wheel of the `petsc` extra needs it),
# else python3 (everything but the iterative solver works on 3.11).
new_enough() { "$1" -c 'import sys; sys.exit(sys.version_info < (3, 12))' >/dev/null 2>&1; }
for py in python3 python3.13 python3.12; do
    if command -v "$py" >/dev/null 2>&1 && new_enough "$py"; then command -v "$py"; exit 0; fi
done
for py in "${PYENV_ROOT:-$HOME/.pyenv}"/versions/3.1[2-9]*/bin/python3; do
    if [ -x "$py" ] && new_enough "$py"; then echo "$py"; exit 0; fi
done
echo python3
