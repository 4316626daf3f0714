#!/usr/bin/env bash
# System libraries the Python packages need: SuiteSparse + OpenBLAS for
# scikit-sparse (CHOLMOD), Ipopt for cyipopt (pip builds it against the
# system library), and EGL with Mesa's software renderer for the headless
# pictures of a run (the VTK wheel loads libEGL at run time; contopt sets
# VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow, no display needed).
# Installed with apt-get when we are root on a Debian/Ubuntu machine and they
# are missing; otherwise we say what to install and go on (pypardiso and SciPy
# do not need them; cyipopt and the pictures do).
set -u
need=()
for pkg in libsuitesparse-dev libopenblas0-pthread pkg-config coinor-libipopt-dev \
           libegl1 libegl-mesa0 libgl1-mesa-dri libgl1; do
    dpkg -s "$pkg" >/dev/null 2>&1 || need+=("$pkg")
done
[ ${#need[@]} -eq 0 ] && exit 0
if [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then
    echo "installing system packages: ${need[*]}"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq >/dev/null && apt-get install -y -qq "${need[@]}" >/dev/null \
        || echo "warning: apt-get could not install ${need[*]}; CHOLMOD (and, without coinor-libipopt-dev, cyipopt; without libegl1 libegl-mesa0 libgl1-mesa-dri, the pictures of a run) will be unavailable"
else
    echo "note: install ${need[*]} (e.g. sudo apt-get install ${need[*]}): CHOLMOD and cyipopt (IPOPT) need them, and the pictures of a run need EGL (libegl1 libegl-mesa0 libgl1-mesa-dri)"
fi
exit 0
