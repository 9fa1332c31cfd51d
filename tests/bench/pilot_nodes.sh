#!/usr/bin/env bash
# The README's "SBVH" table: nodes an AO ray visits per scene, from the host pilot of
# `--ao-order` (the GPU's walk over the GPU's nodes, traced on the CPU; no GPU needed), in
# both child orders, with the triangle slots and build time of the BVH. Compare builds by
# running it with each binary (or each --bvh-quality).
# usage: [RUNNER=target/release/runner] [QUALITY=high] bash tests/bench/pilot_nodes.sh \
#        rocks-1m spheres-1m city-1m grass-1m shell-1m path/to/scene.gltf ...
set -uo pipefail
RUNNER=${RUNNER:-target/release/runner}
QUALITY=${QUALITY:-high}
echo "scene | nodes per AO ray, front to back / back to front | BVH"
for scene in "$@"; do
  out=$(RUNNER_LOG=info "$RUNNER" bench --backend cpu --integrator ao --spp 1 --ao-rays 64 \
    --bvh-quality "$QUALITY" --scene "$scene" --width 16 --height 9 --runs 1 --warmup 0 2>&1)
  nodes=$(grep -o "[0-9.]* nodes per ray front to back, [0-9.]* back" <<<"$out" |
    sed 's/ nodes per ray front to back, / \/ /; s/ back$//')
  bvh=$(grep -o "build [0-9.]* ms, quality [a-z]*, [0-9]* triangle slots" <<<"$out")
  err=$(grep -m1 "^error" <<<"$out")
  echo "$(basename "$scene") | ${nodes:-$err} | $bvh"
done
