#!/usr/bin/env bash
# The README's current GPU performance tables in one device run: the benchmark suite (AO,
# NEE and pt on the five 1M-triangle scenes), the path kernels at 1080p on three scenes
# (pt, nee, mis and ris at depth 8; NEE at depth 2, direct light, as issue 16's target) and
# the ReSTIR frame. Run it on the device machine from the repository root with the Vulkan
# loader's .debs in .gl/ (device README).
# usage: [RUNNER=path/to/runner] bash tests/bench/readme_perf.sh
set -uo pipefail
R=${RUNNER:-target/release/runner}
. tests/bench/device_env.sh
nvidia-smi --query-gpu=name,driver_version,clocks.sm --format=csv,noheader
HD=(--backend gpu --width 1920 --height 1080)
"$R" bench --suite "${HD[@]}"
ms() { # label, bench arguments: median ms per frame and per pass (a ReSTIR frame of the
  # --spp 8 sequence; one spp elsewhere), rays per second
  local out
  out=$("$R" bench "${HD[@]}" --runs 5 --warmup 3 "${@:2}" 2>&1)
  echo "$1 $(echo "$out" | awk '/^ms\/(frame|pass)/{print $1, $5} /^rays\/s/{print $2, $3}' | xargs)"
}
for s in cornell-box many-lights rocks-1m; do
  for i in pt nee mis ris; do ms "$s $i depth-8" --scene "$s" --integrator "$i" --max-depth 8 --spp 1; done
done
ms "many-lights nee direct" --scene many-lights --integrator nee --max-depth 2 --spp 1
for s in many-lights cornell-box; do
  for b in unbiased biased; do
    ms "$s restir $b" --scene "$s" --integrator restir --max-depth 2 --spp 8 --restir-bias "$b"
  done
done
