#!/usr/bin/env bash
# Test command: installs what is missing, builds with the tests, runs the whole suite (ctest).
# The dataset tests read ../shared/datasets (or $UWBLOC_DATA_DIR).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
bash scripts/build.sh -DBUILD_TESTS=ON -DBUILD_APPS=ON
cd build
ctest --output-on-failure --parallel "$(nproc)"
