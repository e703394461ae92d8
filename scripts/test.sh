#!/usr/bin/env bash
# Test command: installs what is missing, builds with the tests, runs the whole suite (ctest);
# then the same suite under AddressSanitizer and UndefinedBehaviorSanitizer (build-asan/), and
# every libFuzzer target for 20 s from its seed corpus (build-fuzz/, clang).
# The dataset tests read ../shared/datasets (or $UWBLOC_DATA_DIR).
set -euo pipefail
cd "$(dirname "$0")/.."
start=$SECONDS
UWBLOC_WITH_TEST_TOOLS=1 bash scripts/install-deps.sh
bash scripts/build.sh -DBUILD_TESTS=ON -DBUILD_APPS=ON
(cd build && ctest --output-on-failure --parallel "$(nproc)")
echo "release suite done after $((SECONDS - start)) s; the sanitised suite next"
bash scripts/sanitize.sh
echo "sanitised suite done after $((SECONDS - start)) s; fuzzing next"
bash scripts/fuzz.sh 20
echo "test command done in $((SECONDS - start)) s"
