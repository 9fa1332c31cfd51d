#!/usr/bin/env bash
# The README's CPU-backend tables: AO rays/s of `runner bench --backend cpu` against Embree 3
# (Debian's libembree-dev) on the same generated scenes, camera, ray count (64 per camera
# hit, 320x180) and AO distance.
#   default:  all cores each, one after the other; best of ROUNDS rounds of each.
#   PAIRED=1: per core, for a box whose speed drifts (shared VMs): the runner and Embree run
#             at the same time, one thread each, each pinned to its own core (taskset -c 0
#             and 1), swapping cores every round, so that a slow spell slows both. Prints
#             each round's rates and ratio, then the median ratio per scene.
# usage: RUNNER=path/to/runner [PAIRED=1] tests/bench/cpu_vs_embree.sh [ROUNDS] [SCENE...]
set -euo pipefail
R=${RUNNER:-runner}
paired=${PAIRED:-0}
rounds=${1:-$([ "$paired" = 1 ] && echo 4 || echo 2)}; shift || true
scenes=("${@:-spheres-1m rocks-1m city-1m grass-1m shell-1m}")
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
cc -O2 -o "$dir/embree_ao" "$(dirname "$0")/embree_ao.c" -lembree3 -lpthread -lm

runner_rate() { # threads, core list
  RAYON_NUM_THREADS=$1 taskset -c "$2" "$R" bench --backend cpu --scene "$s" --integrator ao \
    --spp 1 --ao-rays 64 --width 320 --height 180 --runs 5 --warmup 1 --bvh-quality high 2>&1 |
    awk '/^rays\/frame/{r=$2} /^ms\/frame/{print r / $3 / 1000}'
}
embree_rate() { # threads, core list, frames (best of them)
  taskset -c "$2" "$dir/embree_ao" "$dir/$s.obj" 320 180 64 0 "$1" "$3" 2>/dev/null |
    awk '{print $5}' | sort -n | tail -1
}
median() { sort -n | awk '{v[NR]=$1} END{print (NR % 2) ? v[(NR+1)/2] : (v[NR/2] + v[NR/2+1]) / 2}'; }
max() { awk -v a="$1" -v b="$2" 'BEGIN{print (b > a) ? b : a}'; }

threads=$(nproc)
all="0-$((threads - 1))"
if [ "$paired" = 1 ]; then
  echo "| scene | round | runner (1 thread) | Embree 3 (1 thread) | ratio |"
  echo "| --- | ---: | ---: | ---: | ---: |"
else
  echo "| scene | runner (cpu, $threads threads) | Embree 3 ($threads threads) | ratio |"
  echo "| --- | ---: | ---: | ---: |"
fi
for s in ${scenes[*]}; do
  "$R" generate "$s" --out "$dir/$s.obj" >/dev/null 2>&1
  if [ "$paired" = 1 ]; then
    ratios=()
    for round in $(seq "$rounds"); do
      a=$((round % 2)); b=$((1 - a))
      # The runner loads its BVH meanwhile, so Embree runs more frames.
      runner_rate 1 "$a" >"$dir/r" & embree_rate 1 "$b" 20 >"$dir/e"; wait
      r=$(cat "$dir/r"); e=$(cat "$dir/e")
      ratio=$(awk -v r="$r" -v e="$e" 'BEGIN{printf "%.3f", r / e}')
      ratios+=("$ratio")
      awk -v s="$s" -v n="$round" -v r="$r" -v e="$e" -v q="$ratio" \
        'BEGIN{printf "| %s | %d | %.2f M rays/s | %.2f M rays/s | %s |\n", s, n, r, e, q}'
    done
    echo "$s median ratio $(printf '%s\n' "${ratios[@]}" | median)"
  else
    best_r=0 best_e=0
    for _ in $(seq "$rounds"); do
      best_r=$(max "$best_r" "$(runner_rate "$threads" "$all")")
      best_e=$(max "$best_e" "$(embree_rate "$threads" "$all" 5)")
    done
    awk -v s="$s" -v r="$best_r" -v e="$best_e" \
      'BEGIN{printf "| %s | %.2f M rays/s | %.2f M rays/s | %.2f |\n", s, r, e, r / e}'
  fi
done
