#!/usr/bin/env bash
# The CUDA port of the AO walk (ao.cu) against the Vulkan kernel, and Nsight Compute profiles
# of it. Run on the device machine from the repository root, with the Vulkan loader's .debs in
# .gl/ and two binaries built here (strip + xz): the runner (RUNNER_XZ, default
# .dev/runner-main.xz) and `cargo build --release --example dump_ao` (DUMP_XZ, default
# .dev/dump_ao.xz). Writes ao.sass, and per profiled scene an .ncu-rep, its details page and
# its SASS source page (per-instruction counts and stall samples) as CSV, to $OUT.
# usage: [SC="scenes"] [VK="scenes for the Vulkan bench"] [PROF="scenes to profile"]
#        [BASE="ao ao_fast ao_notri ao_count"] [EXTRA="NO_CANON TRI_ONE+EDGE_XOR ..."] bash tests/bench/cuda_ao/run.sh
set -u
. tests/bench/device_env.sh
R=/tmp/runner; xz -dc ${RUNNER_XZ:-.dev/runner-main.xz} > $R; chmod +x $R
D=/tmp/dump_ao; xz -dc ${DUMP_XZ:-.dev/dump_ao.xz} > $D; chmod +x $D
nvidia-smi --query-gpu=name,clocks.sm,clocks.max.sm --format=csv,noheader
SC=${SC:-"shell-1m spheres-1m grass-1m rocks-1m city-1m"}
VK=${VK-"shell-1m spheres-1m grass-1m"}
EXTRA=${EXTRA:-}
PROF=${PROF-"shell-1m spheres-1m"}
( cd tests/bench/cuda_ao
nvcc --version | tail -1
nvcc -O3 -arch=sm_90 -lineinfo -Xptxas -v -o /tmp/ao ao.cu 2>&1 | grep -E "registers|error|stack|spill"
nvcc -O3 -arch=sm_90 -DCOUNT -o /tmp/ao_count ao.cu 2>&1 | grep error
nvcc -O3 -arch=sm_90 -DNO_TRI -o /tmp/ao_notri ao.cu 2>&1 | grep error
nvcc -O3 -arch=sm_90 -use_fast_math -o /tmp/ao_fast ao.cu 2>&1 | grep error
for v in $EXTRA; do nvcc -O3 -arch=sm_90 $(echo "-D$v" | sed "s/+/ -D/g") -o /tmp/ao_$v ao.cu 2>&1 | grep error; done
cuobjdump --dump-sass /tmp/ao > $OUT/ao.sass )
for s in $SC; do
  DUMP_REF=1 $D /tmp/$s --scene $s --width 1920 --height 1080 --bvh-quality high --integrator ao --spp 1 --ao-rays 64 2>&1 | tail -1
  for v in ${BASE-ao ao_fast ao_notri ao_count} $(for e in $EXTRA; do echo ao_$e; done); do echo -n "$v "; /tmp/$v /tmp/$s 10; done
done
for s in $VK; do
  echo "vulkan $s: $($R bench --backend gpu --scene $s --width 1920 --height 1080 --integrator ao --spp 1 --ao-rays 64 --bvh-quality high --runs 5 --warmup 3 2>&1 | grep -iE 'frame|rays/s' | tr '\n' ' ')"
done
for s in $PROF; do
  timeout 200 ncu --clock-control none --set full -k ao_kernel -s 3 -c 1 -o $OUT/$s /tmp/ao /tmp/$s 1 > $OUT/ncu_$s.log 2>&1
  tail -3 $OUT/ncu_$s.log
  ncu -i $OUT/$s.ncu-rep --page details > $OUT/${s}_details.txt 2>&1
  ncu -i $OUT/$s.ncu-rep --page source --csv --print-source sass > $OUT/${s}_source.csv 2>&1
  ls -la $OUT
done
