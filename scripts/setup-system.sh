#!/usr/bin/env bash
# System libraries some extras need; the core (`pip install contopt`) needs none of them.
#
#   setup-system.sh demo   EGL with Mesa's software renderer, for the headless pictures of a run
#                          (the VTK wheel of the viz extra loads libEGL at run time; contopt sets
#                          VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow, no display needed)
#   setup-system.sh test   (the default) also SuiteSparse + OpenBLAS for scikit-sparse (the cholmod
#                          extra), Ipopt and pkg-config for cyipopt (the ipopt extra: pip builds it
#                          against the system library), and chromium for the test that opens a
#                          run's report.html in a headless browser (Playwright, from the dev extra,
#                          drives this system browser; WebGL through its bundled SwiftShader), and
#                          the X and GLU libraries the gmsh wheel (the cad extra) loads
#
# Installed with apt-get when we are root on a Debian/Ubuntu machine and they are missing;
# otherwise we say what to install and go on: never fatal (without them the extras that need
# them do not install or draw, and contopt says so; docs/install.md).
set -u
mode="${1:-test}"
case "$mode" in
    demo) wanted=(libegl1 libegl-mesa0 libgl1-mesa-dri libgl1) ;;
    test) wanted=(libsuitesparse-dev libopenblas0-pthread pkg-config coinor-libipopt-dev
                  libegl1 libegl-mesa0 libgl1-mesa-dri libgl1
                  libglu1-mesa libxcursor1 libxft2 libxinerama1) ;;
    *) echo "setup-system.sh: unknown mode '$mode'; use demo or test" >&2; exit 2 ;;
esac
command -v dpkg >/dev/null 2>&1 || { echo "note: not a Debian/Ubuntu system: see docs/install.md for the system libraries of the extras"; exit 0; }
need=()
for pkg in "${wanted[@]}"; do
    dpkg -s "$pkg" >/dev/null 2>&1 || need+=("$pkg")
done
browser=()
if [ "$mode" = test ]; then
    dpkg -s chromium >/dev/null 2>&1 || command -v chromium >/dev/null 2>&1 || browser+=(chromium)
fi
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
