#!/usr/bin/env bash
# System libraries the Python packages need: SuiteSparse + OpenBLAS for
# scikit-sparse (CHOLMOD), Ipopt for cyipopt (pip builds it against the
# system library), and EGL with Mesa's software renderer for the headless
# pictures of a run (the VTK wheel loads libEGL at run time; contopt sets
# VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow, no display needed); and
# chromium for the test that opens a run's report.html in a headless browser
# (Playwright, from the dev extra, drives this system browser; WebGL through
# its bundled SwiftShader, no GPU needed).
# Installed with apt-get when we are root on a Debian/Ubuntu machine and they
# are missing; otherwise we say what to install and go on (pypardiso and SciPy
# do not need them; cyipopt, the pictures and the browser test do).
set -u
need=()
for pkg in libsuitesparse-dev libopenblas0-pthread pkg-config coinor-libipopt-dev \
           libegl1 libegl-mesa0 libgl1-mesa-dri libgl1; do
    dpkg -s "$pkg" >/dev/null 2>&1 || need+=("$pkg")
done
browser=()
dpkg -s chromium >/dev/null 2>&1 || command -v chromium >/dev/null 2>&1 || browser+=(chromium)
[ ${#need[@]} -eq 0 ] && [ ${#browser[@]} -eq 0 ] && exit 0
if [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then
    echo "installing system packages: ${need[*]} ${browser[*]}"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq >/dev/null
    if [ ${#need[@]} -gt 0 ]; then
        apt-get install -y -qq "${need[@]}" >/dev/null \
            || echo "warning: apt-get could not install ${need[*]}; CHOLMOD (and, without coinor-libipopt-dev, cyipopt; without libegl1 libegl-mesa0 libgl1-mesa-dri, the pictures of a run) will be unavailable"
    fi
    # on its own: where the distribution has no chromium package (Ubuntu ships a snap) the rest still installs
    if [ ${#browser[@]} -gt 0 ]; then
        apt-get install -y -qq "${browser[@]}" >/dev/null \
            || echo "warning: apt-get could not install chromium; the browser test of report.html will fail until a chromium is installed (CONTOPT_CHROMIUM=/path/to/it)"
    fi
else
    echo "note: install ${need[*]} ${browser[*]} (e.g. sudo apt-get install ${need[*]} ${browser[*]}): CHOLMOD and cyipopt (IPOPT) need them, the pictures of a run need EGL (libegl1 libegl-mesa0 libgl1-mesa-dri), the browser test of report.html chromium"
fi
exit 0
