#!/usr/bin/env bash
# Installs everything physics-planning needs on a fresh Debian/Ubuntu machine:
# Debian's GNU Go (the MuJoGo opponent) and the Python package with its pinned
# dependencies (mujoco 3.17.0 + dm-control 1.0.50, CPU torch 2.13.0, ...).
set -euo pipefail
cd "$(dirname "$0")/.."
SUDO=""
if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi
if ! command -v gnugo >/dev/null 2>&1 && [ ! -x /usr/games/gnugo ]; then
  echo "== installing gnugo (apt-get)"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq gnugo
fi
echo "== installing the Python package and its dependencies (pip)"
python -m pip install -q -e '.[dev]'
echo "== installed"
