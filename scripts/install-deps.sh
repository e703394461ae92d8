#!/usr/bin/env bash
# Installs the Debian 12 packages uwbloc needs, only those missing. Uses sudo when not root.
# Quiet: one line per stage; apt's full output goes to install-deps.log and is printed only
# when a stage fails.
set -euo pipefail
cd "$(dirname "$0")/.."
packages=(build-essential cmake ninja-build ccache pkg-config
          libmrpt-dev mrpt-common libeigen3-dev libceres-dev libcli11-dev nlohmann-json3-dev
          libgtest-dev libbenchmark-dev libxgboost-dev libmatio-dev libopencv-dev
          libjs-chart.js)
if [ "${UWBLOC_WITH_MRPT_APPS:-0}" = "1" ]; then packages+=(mrpt-apps); fi
if [ "${UWBLOC_WITH_FUZZ:-0}" = "1" ]; then packages+=(clang libclang-rt-14-dev); fi
# The test command's tools: a headless browser for report.html, GNU parallel for the sweep test.
if [ "${UWBLOC_WITH_TEST_TOOLS:-0}" = "1" ]; then packages+=(chromium-headless-shell parallel); fi
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
log=install-deps.log
: > "$log"
source scripts/quiet.sh
stage "Updating the package lists" $SUDO apt-get update
stage "Installing ${#missing[@]} packages: ${missing[*]}" \
  env DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y --no-install-recommends "${missing[@]}"
