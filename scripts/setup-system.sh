#!/usr/bin/env bash
# System libraries the Python packages need: SuiteSparse + OpenBLAS for
# scikit-sparse (CHOLMOD), and Ipopt for cyipopt (pip builds it against the
# system library). Installed with apt-get when we are root on a Debian/Ubuntu
# machine and they are missing; otherwise we say what to install and go on
# (pypardiso and SciPy do not need them; cyipopt does).
set -u
need=()
for pkg in libsuitesparse-dev libopenblas0-pthread pkg-config coinor-libipopt-dev; do
    dpkg -s "$pkg" >/dev/null 2>&1 || need+=("$pkg")
done
[ ${#need[@]} -eq 0 ] && exit 0
if [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then
    echo "installing system packages: ${need[*]}"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq >/dev/null && apt-get install -y -qq "${need[@]}" >/dev/null \
        || echo "warning: apt-get could not install ${need[*]}; CHOLMOD (and, without coinor-libipopt-dev, cyipopt) will be unavailable"
else
    echo "note: install ${need[*]} (e.g. sudo apt-get install ${need[*]}): CHOLMOD and cyipopt (IPOPT) need them"
fi
exit 0
