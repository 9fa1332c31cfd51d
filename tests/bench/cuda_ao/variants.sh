#!/usr/bin/env bash
# Variants of the CUDA port (ao.cu) against each other: two rounds of each on every scene
# (ms per frame, the port's comparison with the CPU's AO), nodes per ray from each one's
# COUNT build, its SASS to $OUT, and optionally a few Nsight Compute figures per variant.
# Run on the device machine from the repository root, with `cargo build --release --example
# dump_ao` built here (strip + xz) as DUMP_XZ (default .dev/dump_ao.xz). A variant is
# macros joined by +, NAME=VALUE for a value.
# usage: V="TRI_ONE+EDGE_XOR TRI_ONE+EDGE_XOR+F16+F16_MARGIN=960" [SC="scenes"]
#        [PROF="scenes to profile"] bash tests/bench/cuda_ao/variants.sh
set -u
D=/tmp/dump_ao; xz -dc ${DUMP_XZ:-.dev/dump_ao.xz} > $D; chmod +x $D
nvidia-smi --query-gpu=name,clocks.sm,clocks.max.sm --format=csv,noheader
V=${V:-"TRI_ONE+EDGE_XOR TRI_ONE+EDGE_XOR+SPLIT_STACK"}
SC=${SC:-"spheres-1m grass-1m shell-1m rocks-1m city-1m"}
name() { echo "$1" | tr '+=' '__'; }
flags() { echo "-D$1" | sed "s/+/ -D/g"; }
dump() { DUMP_REF=1 $D /tmp/$1 --scene $1 --width 1920 --height 1080 --bvh-quality high \
  --integrator ao --spp 1 --ao-rays 64 2>&1 | tail -1; }
( cd tests/bench/cuda_ao
nvcc --version | tail -1
for v in $V; do
  n=$(name $v)
  nvcc -O3 -arch=sm_90 -Xptxas -v $(flags $v) -o /tmp/ao_$n ao.cu 2>&1 | grep -E "error|registers"
  nvcc -O3 -arch=sm_90 -DCOUNT $(flags $v) -o /tmp/aoc_$n ao.cu 2>&1 | grep error
  cuobjdump --dump-sass /tmp/ao_$n > $OUT/$n.sass
done )
for s in $SC; do
  dump $s
  for r in 1 2; do for v in $V; do echo -n "r$r $(name $v) "; /tmp/ao_$(name $v) /tmp/$s 10; done; done
  for v in $V; do echo -n "count $(name $v) "; /tmp/aoc_$(name $v) /tmp/$s 1 | head -1; done
  rm -rf /tmp/$s
done
for s in ${PROF:-}; do
  dump $s
  for v in $V; do
    timeout 200 ncu --clock-control none --section SpeedOfLight --section WarpStateStats \
      --section MemoryWorkloadAnalysis -k ao_kernel -s 3 -c 1 /tmp/ao_$(name $v) /tmp/$s 1 > /tmp/ncu.txt 2>&1
    echo "== ncu $(name $v) $s"
    grep -E 'L2 Cache Throughput|L1/TEX Cache Throughput|Compute \(SM\) Throughput|Duration|Avg. Active Threads|L1/TEX Hit|L2 Hit Rate|Mem Busy' /tmp/ncu.txt
  done
  rm -rf /tmp/$s
done
