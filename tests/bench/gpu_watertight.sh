#!/usr/bin/env bash
# The README's GPU watertightness figure: from inside shell-1m (black, closed) under a white
# sky, camera rays only, 1080p x 64 spp (133 M rays) per view; a lit pixel is a ray that
# slipped between two triangles. `runner compare` against a black image counts them (its
# "identical" share is 100% when none leaked). Both BVH qualities, three views.
# Run it on the device machine from the repository root, the Vulkan loader's .debs in .gl/.
# usage: RUNNER=path/to/runner [SPP=64 WIDTH=1920 HEIGHT=1080] bash tests/bench/gpu_watertight.sh [SCENE]
set -uo pipefail
R=${RUNNER:-runner}
scene=${1:-shell-1m}
. tests/bench/device_env.sh
dir=$(mktemp -d)
# The runner refuses to render an image it knows is black, so the reference is written here.
spp=${SPP:-64} w=${WIDTH:-1920} h=${HEIGHT:-1080}
python3 "$(dirname "$0")/black_exr.py" "$w" "$h" "$dir/black.exr" || exit 1
common="--backend gpu --scene $scene --integrator pt --max-depth 1 --spp $spp --width $w --height $h --sky 1,1,1"
for q in auto high; do
  for v in centre pole grazing; do
    case $v in
      centre) view=() ;;
      pole) view=(--eye 0,0.5,0 --target 0,1,0.01) ;;
      grazing) view=(--eye 0.95,0,0 --target 1,0,0.01 --fov 150) ;;
    esac
    $R render $common --bvh-quality $q "${view[@]}" --out "$dir/lit.exr" >/dev/null 2>&1 || { echo "$q $v: render failed"; continue; }
    echo "$q $v: $($R compare "$dir/lit.exr" "$dir/black.exr" 2>&1)"
  done
done
rm -rf "$dir"
