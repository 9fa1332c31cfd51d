#!/usr/bin/env bash
# ReSTIR under motion: the camera orbits DEG degrees a frame; relMSE of the 16th frame
# (mean over seeds) against a converged reference at that frame's camera, for ReSTIR with
# and without temporal reuse and for RIS.
# usage: RUNNER=path/to/runner tests/bench/restir_orbit.sh SCENE WIDTH HEIGHT [DEG] [SEEDS]
set -euo pipefail
R=${RUNNER:-runner}
scene=$1 w=$2 h=$3 deg=${4:-0.5} seeds=${5:-3}
dir=$(mktemp -d)
common=(--scene "$scene" --max-depth 2 --width "$w" --height "$h" --backend gpu --orbit "$deg")
$R render "${common[@]}" --integrator mis --spp 8192 --first-frame 15 --out "$dir/ref.exr" 2>/dev/null
measure() {
  local label=$1; shift
  local sum=0
  for s in $(seq 1 "$seeds"); do
    $R render "${common[@]}" --seed "$s" --out "$dir/o.exr" "$@" 2>/dev/null
    sum=$(awk -v a="$sum" -v b="$($R compare "$dir/o.exr" "$dir/ref.exr" | awk '{print $4}')" 'BEGIN{print a+b}')
  done
  awk -v l="$label" -v s="$sum" -v n="$seeds" 'BEGIN{printf "| %s | %.4f |\n", l, s/n}'
}
echo "| frame 16 of an orbit ($deg°/frame) | relMSE |"
echo "| --- | ---: |"
measure "RIS, 256 candidates" --integrator ris --spp 1 --candidates 256 --first-frame 15
for bias in biased unbiased; do
  measure "ReSTIR $bias" --integrator restir --spp 1 --frames 16 --restir-bias "$bias"
  measure "ReSTIR $bias, no temporal reuse" --integrator restir --spp 1 --frames 16 --restir-bias "$bias" --no-temporal
done
rm -rf "$dir"
