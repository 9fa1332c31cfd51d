#!/usr/bin/env bash
# The README's real-time ReSTIR table: relMSE of ONE frame (what a viewer shows) after N
# frames of history, mean over seeds, against a converged reference; and ms per frame.
# usage: RUNNER=path/to/runner tests/bench/restir_table.sh SCENE WIDTH HEIGHT [SEEDS] [REF_SPP]
set -euo pipefail
R=${RUNNER:-runner}
scene=$1 w=$2 h=$3 seeds=${4:-3} ref_spp=${5:-8192}
dir=$(mktemp -d)
common=(--scene "$scene" --max-depth 2 --width "$w" --height "$h" --backend gpu)
ref=$dir/ref.exr
$R render "${common[@]}" --integrator mis --spp "$ref_spp" --out "$ref" 2>/dev/null
# mean relMSE and image mean (relative to the reference) over seeds of one configuration
measure() {
  local label=$1; shift
  local sum=0 ratio=0
  for s in $(seq 1 "$seeds"); do
    $R render "${common[@]}" --seed "$s" --out "$dir/o.exr" "$@" 2>/dev/null
    line=$($R compare "$dir/o.exr" "$ref")
    sum=$(awk -v a="$sum" -v b="$(echo "$line" | awk '{print $4}')" 'BEGIN{print a+b}')
    ratio=$(echo "$line" | sed -E 's/.*mean ([0-9.eE+-]+) vs ([0-9.eE+-]+).*/\1 \2/' | awk -v a="$ratio" '{print a+$1/$2}')
  done
  awk -v l="$label" -v s="$sum" -v r="$ratio" -v n="$seeds" 'BEGIN{printf "| %s | %.4f | %.3f |\n", l, s/n, r/n}'
}
ms() { $R bench "${common[@]}" --json --runs 5 "$@" 2>/dev/null | sed -E 's/.*"frame_ms_median":([0-9.]+).*/\1/'; }
echo "| one frame of | relMSE | mean / reference |"
echo "| --- | ---: | ---: |"
measure "NEE, 1 spp ($(ms --integrator nee --spp 1) ms)" --integrator nee --spp 1
for c in 32 256 1024; do
  measure "RIS, $c candidates ($(ms --integrator ris --spp 1 --candidates "$c") ms)" --integrator ris --spp 1 --candidates "$c"
done
for bias in biased unbiased; do
  t=$(ms --integrator restir --spp 8 --restir-bias "$bias")
  per=$(awk -v t="$t" 'BEGIN{printf "%.2f", t/8}')
  for n in 1 4 16 64; do
    measure "ReSTIR $bias, after $n frames ($per ms/frame)" --integrator restir --spp 1 --frames "$n" --restir-bias "$bias"
  done
  measure "ReSTIR $bias, 16 frames, temporal only" --integrator restir --spp 1 --frames 16 --restir-bias "$bias" --spatial-passes 0
done
rm -rf "$dir"
