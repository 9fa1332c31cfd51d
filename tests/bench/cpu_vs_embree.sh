#!/usr/bin/env bash
# The README's CPU-backend table: AO rays/s of `runner bench --backend cpu` against Embree 3
# (Debian's libembree-dev) on the same generated scenes, camera, ray count and AO distance,
# the same number of threads (all cores). Best of ROUNDS rounds of each.
# usage: RUNNER=path/to/runner tests/bench/cpu_vs_embree.sh [ROUNDS] [SCENE...]
set -euo pipefail
R=${RUNNER:-runner}
rounds=${1:-2}; shift || true
scenes=("${@:-spheres-1m rocks-1m city-1m grass-1m shell-1m}")
dir=$(mktemp -d)
cc -O2 -o "$dir/embree_ao" "$(dirname "$0")/embree_ao.c" -lembree3 -lpthread -lm
threads=$(nproc)
echo "| scene | runner (cpu, $threads threads) | Embree 3 ($threads threads) | ratio |"
echo "| --- | ---: | ---: | ---: |"
for s in ${scenes[*]}; do
  $R generate "$s" --out "$dir/$s.obj" >/dev/null 2>&1
  best_r=0 best_e=0
  for _ in $(seq "$rounds"); do
    out=$($R bench --backend cpu --scene "$s" --integrator ao --spp 1 --ao-rays 64 --width 320 \
      --height 180 --runs 5 --warmup 1 --bvh-quality high 2>&1)
    r=$(echo "$out" | awk '/^rays\/frame/{r=$2} /^ms\/frame/{print r / $3 / 1000}')
    e=$("$dir/embree_ao" "$dir/$s.obj" 320 180 64 0 "$threads" 5 2>/dev/null | awk '{print $5}' | sort -n | tail -1)
    best_r=$(awk -v a="$best_r" -v b="$r" 'BEGIN{print (b > a) ? b : a}')
    best_e=$(awk -v a="$best_e" -v b="$e" 'BEGIN{print (b > a) ? b : a}')
  done
  awk -v s="$s" -v r="$best_r" -v e="$best_e" 'BEGIN{printf "| %s | %.2f M rays/s | %.2f M rays/s | %.2f |\n", s, r, e, r / e}'
done
rm -rf "$dir"
