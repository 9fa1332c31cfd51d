#!/usr/bin/env bash
# The CPU backend against Embree 3 per core, on a box whose speed drifts (shared VMs): the
# runner and Embree run at the same time, one thread each, each pinned to its own core,
# and swap cores every round, so that a slow spell slows both. Same workload as
# cpu_vs_embree.sh (AO, 64 rays per camera hit, 320x180, the same generated scenes).
# Prints each round's M rays/s of both and their ratio, then the median ratio per scene.
# Needs two cores (taskset -c 0 and 1).
# usage: RUNNER=path/to/runner tests/bench/cpu_vs_embree_paired.sh [ROUNDS] [SCENE...]
set -euo pipefail
R=${RUNNER:-runner}
rounds=${1:-4}; shift || true
scenes=("${@:-spheres-1m rocks-1m city-1m grass-1m shell-1m}")
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
cc -O2 -o "$dir/embree_ao" "$(dirname "$0")/embree_ao.c" -lembree3 -lpthread -lm
runner_rate() { # core
  RAYON_NUM_THREADS=1 taskset -c "$1" "$R" bench --backend cpu --scene "$s" --integrator ao \
    --spp 1 --ao-rays 64 --width 320 --height 180 --runs 5 --warmup 1 --bvh-quality high 2>&1 |
    awk '/^rays\/frame/{r=$2} /^ms\/frame/{print r / $3 / 1000}'
}
embree_rate() { # core; the runner loads its BVH meanwhile, so Embree runs more frames
  taskset -c "$1" "$dir/embree_ao" "$dir/$s.obj" 320 180 64 0 1 20 2>/dev/null |
    awk '{print $5}' | sort -n | tail -1
}
echo "| scene | round | runner (1 thread) | Embree 3 (1 thread) | ratio |"
echo "| --- | ---: | ---: | ---: | ---: |"
for s in ${scenes[*]}; do
  "$R" generate "$s" --out "$dir/$s.obj" >/dev/null 2>&1
  ratios=()
  for round in $(seq "$rounds"); do
    a=$((round % 2)); b=$((1 - a))
    runner_rate "$a" >"$dir/r" & embree_rate "$b" >"$dir/e"; wait
    r=$(cat "$dir/r"); e=$(cat "$dir/e")
    ratio=$(awk -v r="$r" -v e="$e" 'BEGIN{printf "%.3f", r / e}')
    ratios+=("$ratio")
    awk -v s="$s" -v n="$round" -v r="$r" -v e="$e" -v q="$ratio" \
      'BEGIN{printf "| %s | %d | %.2f M rays/s | %.2f M rays/s | %s |\n", s, n, r, e, q}'
  done
  echo "$s median ratio $(printf '%s\n' "${ratios[@]}" | sort -n | awk '{v[NR]=$1} END{print (NR % 2) ? v[(NR+1)/2] : (v[NR/2] + v[NR/2+1]) / 2}')"
done
