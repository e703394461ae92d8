#!/usr/bin/env bash
# Configures and builds uwbloc in build/ (Release). Extra arguments go to CMake. Quiet: one line
# per stage; the compiler's full output goes to build.log and is printed only on a failure.
set -euo pipefail
cd "$(dirname "$0")/.."
generator=()
if command -v ninja >/dev/null; then generator=(-G Ninja); fi
log=build.log
: > "$log"
run() {  # run "description" command...
  local what="$1"
  shift
  echo "$what"
  if ! "$@" >> "$log" 2>&1; then
    echo "failed: $what; the full output ($log):"
    cat "$log"
    exit 1
  fi
}
if [ ! -f build/CMakeCache.txt ]; then
  run "Configuring build/" cmake -S . -B build "${generator[@]}" -DCMAKE_BUILD_TYPE=Release "$@"
else
  run "Configuring build/" cmake -S . -B build "$@"
fi
run "Building ($(nproc) jobs)" cmake --build build --parallel "$(nproc)"
