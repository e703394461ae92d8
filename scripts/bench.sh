#!/usr/bin/env bash
# Builds and runs the benchmarks (per-step cost of every method on the MRPT demo).
set -euo pipefail
cd "$(dirname "$0")/.."
UWBLOC_WITH_MRPT_APPS=1 bash scripts/install-deps.sh  # MRPT pf-localization, the peer
bash scripts/build.sh -DBUILD_BENCHMARKS=ON
./build/bench/bench_methods "$@"
./build/bench/bench_vs_mrpt 10 300 15000  # MRPT pf-localization and ro-localization
./build/bench/bench_graph
