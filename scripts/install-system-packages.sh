#!/usr/bin/env bash
# The Debian/Ubuntu packages tippetop needs beyond pip, for the README's install and .ci/run.
#
#   libegl1 libopengl0 libgl1-mesa-dri  offscreen OpenGL on the CPU through EGL (`render`, --videos)
#   libosmesa6                          the OSMesa fallback (MUJOCO_GL=osmesa)
#   chromium fonts-liberation           the tests and the docs build open report.html headless
#   gfortran                            builds numbalsoda's LSODA (the `peers` extra: bench ode)
#
# Runs as root, or as a user with sudo. Usage: bash scripts/install-system-packages.sh [--dry-run]
set -euo pipefail

PACKAGES=(libegl1 libopengl0 libgl1-mesa-dri libosmesa6 chromium fonts-liberation gfortran)

if [[ "${1:-}" == "--dry-run" ]]; then
  echo "${PACKAGES[*]}"
  exit 0
elif [[ $# -gt 0 ]]; then
  echo "install-system-packages.sh: expected no argument or --dry-run, got: $*" >&2
  exit 2
fi

if ! command -v apt-get >/dev/null 2>&1; then
  echo "install-system-packages.sh: expected a Debian/Ubuntu machine (apt-get), found none;" \
       "install the equivalents of: ${PACKAGES[*]}" >&2
  exit 2
fi

if [[ "$(id -u)" -eq 0 ]]; then
  SUDO=()
elif command -v sudo >/dev/null 2>&1; then
  SUDO=(sudo)
else
  echo "install-system-packages.sh: expected root or sudo to install ${PACKAGES[*]}," \
       "found neither" >&2
  exit 2
fi

export DEBIAN_FRONTEND=noninteractive
"${SUDO[@]}" apt-get update -qq
"${SUDO[@]}" env DEBIAN_FRONTEND=noninteractive \
  apt-get install -y -qq --no-install-recommends "${PACKAGES[@]}" >/dev/null
echo "installed: ${PACKAGES[*]}"
