#!/usr/bin/env bash
# Builds and runs the benchmarks (per-step cost of every method on the MRPT demo).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
bash scripts/build.sh -DBUILD_BENCHMARKS=ON
./build/bench/bench_methods "$@"
