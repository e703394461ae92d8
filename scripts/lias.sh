#!/usr/bin/env bash
# The LIAS-CUHKSZ figures of the README: imports the three static runs, calibrates the links'
# biases on them (and leave-one-out for each static run), imports the fast dynamic run with and
# without those biases, and runs the multi-tag and single-tag methods. Heading medians and
# 95th percentiles are in each run's metrics.json (median_yaw_deg, p95_yaw_deg).
#   bash scripts/lias.sh [OUT]        (default OUT: runs/lias; needs a build: scripts/build.sh)
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-runs/lias}"
uwbloc=build/apps/uwbloc/uwbloc
data="${UWBLOC_DATA_DIR:-../shared/datasets}/lias_cuhksz_planar_uwb"
[ -d "$data" ] || { echo "missing $data (set UWBLOC_DATA_DIR)"; exit 1; }
mkdir -p "$out"
for p in 1 2 3; do
  "$uwbloc" import lias "$data/Static/UWB_static_exp_8_14_pos${p}_deg_0.csv" -o "$out/pos$p" > /dev/null
done
"$uwbloc" calibrate "$out"/pos{1,2,3}/dataset.ini -o "$out/cal"
for p in 1 2 3; do
  others=()
  for q in 1 2 3; do [ "$q" != "$p" ] && others+=("$out/pos$q/dataset.ini"); done
  "$uwbloc" calibrate "${others[@]}" -o "$out/cal_without_pos$p" > /dev/null
  "$uwbloc" import lias "$data/Static/UWB_static_exp_8_14_pos${p}_deg_0.csv" -o "$out/pos${p}_loo" \
    --bias "$out/cal_without_pos$p/bias.csv" > /dev/null
  for d in "pos$p" "pos${p}_loo"; do
    echo "== static $d"
    "$uwbloc" run -d "$out/$d/dataset.ini" -m uwb-multitag:smooth=false -o "$out/run_$d" 2> /dev/null \
      | grep -E "^(method|uwb-)"
  done
done
"$uwbloc" import lias "$data/Dynamic/UWB_dynamic_exp_fast.csv" -o "$out/fast"
"$uwbloc" import lias "$data/Dynamic/UWB_dynamic_exp_fast.csv" -o "$out/fast_cal" --bias "$out/cal/bias.csv" > /dev/null
for d in fast fast_cal; do
  echo "== dynamic $d"
  "$uwbloc" compare -d "$out/$d/dataset.ini" \
    -m uwb-multitag,uwb-multitag:smooth=false,uwb-ekf,uwb-ekf:tags=primary,uwb-gn,uwb-gn:tags=primary,uwb-kf,uwb-kf:tags=primary \
    -o "$out/run_$d" 2> /dev/null \
    | grep -E "^(method|uwb-)"
done
