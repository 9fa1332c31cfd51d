#!/usr/bin/env bash
# What fills the L2 in the CUDA port: its throughput's breakdown and the local and global
# sectors and instructions, per variant and scene (Nsight Compute). Run on the device
# machine from the repository root, dump_ao as in variants.sh.
# usage: [V="TRI_ONE+EDGE_XOR TRI_ONE+EDGE_XOR+SPLIT_STACK"] [SC="shell-1m rocks-1m"] \
#        bash tests/bench/cuda_ao/l2_metrics.sh
set -u
D=/tmp/dump_ao; xz -dc ${DUMP_XZ:-.dev/dump_ao.xz} > $D; chmod +x $D
V=${V:-"TRI_ONE+EDGE_XOR TRI_ONE+EDGE_XOR+SPLIT_STACK"}
name() { echo "$1" | tr '+=' '__'; }
( cd tests/bench/cuda_ao
for v in $V; do nvcc -O3 -arch=sm_90 $(echo "-D$v" | sed "s/+/ -D/g") -o /tmp/ao_$(name $v) ao.cu 2>&1 | grep error; done )
M=l1tex__t_sectors_pipe_lsu_mem_local_op_st.sum,l1tex__t_requests_pipe_lsu_mem_local_op_st.sum
M=$M,l1tex__t_sectors_pipe_lsu_mem_local_op_ld.sum,l1tex__t_sectors_pipe_lsu_mem_global_op_ld.sum
M=$M,l1tex__t_sector_hit_rate.pct,lts__t_sectors_srcunit_tex_op_write.sum
M=$M,lts__t_sectors_srcunit_tex_op_read.sum,lts__t_sectors.sum,lts__t_requests.sum
M=$M,smsp__inst_executed_op_local_st.sum,smsp__inst_executed_op_local_ld.sum
M=$M,smsp__inst_executed_op_global_ld.sum,l1tex__m_l1tex2xbar_write_sectors.sum
M=$M,l1tex__m_xbar2l1tex_read_sectors.sum
for s in ${SC:-shell-1m rocks-1m}; do
  $D /tmp/$s --scene $s --width 1920 --height 1080 --bvh-quality high --integrator ao --spp 1 --ao-rays 64 2>&1 | tail -1
  for v in $V; do
    echo "== $(name $v) $s"
    timeout 200 ncu --clock-control none --metrics "$M,breakdown:lts__throughput.avg.pct_of_peak_sustained_elapsed" \
      -k ao_kernel -s 3 -c 1 /tmp/ao_$(name $v) /tmp/$s 1 2>&1 | grep -E '^\s+(l1tex|lts|smsp)__' | awk '{$1=$1};1'
  done
  rm -rf /tmp/$s
done
