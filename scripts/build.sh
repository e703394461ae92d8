#!/usr/bin/env bash
# Configures and builds uwbloc in build/ (Release). Extra arguments go to CMake. Quiet: one line
# per stage; the compiler's full output goes to build.log and is printed only on a failure.
set -euo pipefail
cd "$(dirname "$0")/.."
generator=()
if command -v ninja >/dev/null; then generator=(-G Ninja); fi
log=build.log
: > "$log"
source scripts/quiet.sh
if [ ! -f build/CMakeCache.txt ]; then
  stage "Configuring build/" cmake -S . -B build "${generator[@]}" -DCMAKE_BUILD_TYPE=Release "$@"
else
  stage "Configuring build/" cmake -S . -B build "$@"
fi
stage "Building ($(nproc) jobs)" cmake --build build --parallel "$(nproc)"
