#!/usr/bin/env bash
# Registers and stack of the CUDA port's variants (ao.cu) without a GPU or a CUDA toolkit:
# clang compiles ao.cu to PTX for sm_80, and NVIDIA's ptxas assembles that PTX for sm_90 and
# reports what it used. The numbers are ptxas's on clang's PTX, not on nvcc's: compare
# variants with each other, not with run.sh's; even the differences need not carry over
# (PAD=16: 69 → 80 here, while nvcc 13's build on the device keeps 64 and spills). The
# tools come from pip wheels: ptxas from CUDA 12.9's, and the headers from CUDA 11.8's
# (clang 14 supports CUDA up to 11.5, and reads 11.8's headers with a warning; 12's no
# longer declare what its wrapper includes).
# Needs clang (apt-get install clang-14) and pip. A variant is macros joined by +, as in
# variants.sh. With SASS=dir, each variant's machine code is written there as well
# (nvdisasm, from the nvidia-cuda-nvdisasm wheel).
# usage: [CUDA=/tmp/cuda-pip] [CLANG=clang-14] [SASS=dir]
#        V="TRI_ONE+EDGE_XOR+SPLIT_STACK TRI_ONE+EDGE_XOR+SPLIT_STACK+PAD=16" bash registers.sh
set -eu
C=${CUDA:-/tmp/cuda-pip}
CLANG=${CLANG:-clang-14}
V=${V:-"TRI_ONE+EDGE_XOR TRI_ONE+EDGE_XOR+SPLIT_STACK"}
if [ ! -x "$C/bin/ptxas" ]; then
  w=$(mktemp -d)
  pip download -q --no-deps -d "$w" nvidia-cuda-nvcc-cu12==12.9.86 \
    nvidia-cuda-nvcc-cu11==11.8.89 nvidia-cuda-runtime-cu11==11.8.89 nvidia-curand-cu11==10.3.0.86 \
    nvidia-cuda-nvdisasm==13.5.37
  for f in "$w"/*.whl; do python3 -m zipfile -e "$f" "$w/$(basename "$f" .whl)"; done
  # clang looks for lib64/ to accept the folder as a CUDA installation.
  mkdir -p "$C/bin" "$C/include" "$C/nvvm" "$C/lib64"
  cp "$w"/nvidia_cuda_nvcc_cu12-*/nvidia/cuda_nvcc/bin/ptxas "$C/bin/"
  cp "$w"/nvidia_cuda_nvdisasm-*/nvidia/cu13/bin/nvdisasm "$C/bin/"
  chmod +x "$C/bin/ptxas" "$C/bin/nvdisasm"
  cp -r "$w"/nvidia_cuda_nvcc_cu11-*/nvidia/cuda_nvcc/nvvm/* "$C/nvvm/"
  for h in nvidia_cuda_runtime_cu11-*/nvidia/cuda_runtime nvidia_curand_cu11-*/nvidia/curand \
    nvidia_cuda_nvcc_cu11-*/nvidia/cuda_nvcc; do
    cp -r "$w"/$h/include/* "$C/include/"
  done
  echo "CUDA Version 11.8.0" > "$C/version.txt"
  rm -rf "$w"
fi
cd "$(dirname "$0")"
for v in $V; do
  ptx=$(mktemp --suffix=.ptx)
  "$CLANG" -x cuda --cuda-path="$C" --cuda-gpu-arch=sm_80 --cuda-device-only -O3 -S \
    $(echo "-D$v" | sed "s/+/ -D/g") -o "$ptx" ao.cu 2>&1 | grep -E "error" || true
  cubin=${ptx%.ptx}.cubin
  echo "$v: $("$C/bin/ptxas" -arch=sm_90 -O3 -v "$ptx" -o "$cubin" 2>&1 | grep -o 'Used .*')"
  if [ -n "${SASS:-}" ]; then
    mkdir -p "$SASS"
    "$C/bin/nvdisasm" -c "$cubin" 2>/dev/null > "$SASS/$(echo "$v" | tr '+=' '__').sass"
  fi
  rm -f "$ptx" "$cubin"
done
