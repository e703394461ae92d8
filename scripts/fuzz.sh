#!/usr/bin/env bash
# Builds the libFuzzer targets with clang (ASan + UBSan, in build-fuzz/) and runs each for
# SECONDS (default 20) from its seed corpus in tests/fuzz/corpus/<target>/, keeping what it
# learns in build-fuzz/corpus/<target>/. A finding stops with the reproducer's path.
#   bash scripts/fuzz.sh [SECONDS]        e.g. bash scripts/fuzz.sh 600 for the 10-minute run
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-20}"
UWBLOC_WITH_FUZZ=1 bash scripts/install-deps.sh
if [ ! -f build-fuzz/CMakeCache.txt ]; then
  CC=clang CXX=clang++ cmake -S . -B build-fuzz -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DUWBLOC_FUZZ=ON -DBUILD_TESTS=OFF -DBUILD_APPS=OFF > build-fuzz.log 2>&1 \
    || { cat build-fuzz.log; exit 1; }
fi
cmake --build build-fuzz --target fuzz_ini fuzz_params fuzz_text_readers fuzz_rawlog fuzz_importers > build-fuzz.log 2>&1 \
  || { cat build-fuzz.log; exit 1; }
for target in fuzz_ini fuzz_params fuzz_text_readers fuzz_rawlog fuzz_importers; do
  mkdir -p "build-fuzz/corpus/$target"
  echo "fuzzing $target for ${seconds} s"
  ASAN_OPTIONS=detect_leaks=0:quarantine_size_mb=32 UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1 \
    "build-fuzz/fuzz/$target" -max_total_time="$seconds" -max_len=4096 -timeout=10 \
    -print_final_stats=1 -artifact_prefix="build-fuzz/$target-" \
    "build-fuzz/corpus/$target" "tests/fuzz/corpus/$target" 2>&1 \
    | grep -E "stat::number_of_executed_units|stat::average_exec_per_sec|DONE|ERROR|SUMMARY|Test unit written" || true
  # Crashes, leaks, timeouts and out-of-memory are findings; a slow unit (a legal but large
  # input, e.g. 900 000 particles under ASan) is reported and kept, not a failure.
  # (compgen -G tests each pattern on its own: `ls a* b*` fails when any one pattern matches
  # nothing, which once hid a crash from this check.)
  findings=()
  for kind in crash leak timeout oom; do
    while IFS= read -r f; do findings+=("$f"); done < <(compgen -G "build-fuzz/$target-$kind-*" || true)
  done
  if [ "${#findings[@]}" -gt 0 ]; then
    echo "finding in $target: ${findings[*]}"
    exit 1
  fi
  if compgen -G "build-fuzz/$target-slow-unit-*" > /dev/null; then
    echo "slow inputs (not failures): $(compgen -G "build-fuzz/$target-slow-unit-*" | tr '\n' ' ')"
  fi
done
echo "no finding"
