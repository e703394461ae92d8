#!/usr/bin/env bash
# Main command: installs what is missing, builds, and compares every registered method on the
# MRPT UWB demo (the default dataset). Prints the table and writes runs/mrpt_uwb_demo/.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
bash scripts/build.sh -DBUILD_TESTS=OFF -DBUILD_APPS=ON
./build/apps/uwbloc/uwbloc compare --methods all --out runs/mrpt_uwb_demo "$@"
