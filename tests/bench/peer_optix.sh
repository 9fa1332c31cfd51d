#!/usr/bin/env bash
# Our AO kernel against the peer on the same scenes and the same kind of rays: per scene,
# `runner bench` (AO, 1 spp × 64 rays, 1080p) and Mitsuba 3's OptiX `ray_test` over that
# frame's AO points (tests/bench/peer_optix.py), on the same GPU in the same run.
# First, here: `cargo build --release --bins --example dump_ao && bash
# tests/bench/peer_optix.sh pack`, which strips and packs the two binaries and Mitsuba 3 and
# Dr.Jit from their cp312 wheels (less the variant modules other than cuda_ad_rgb and
# scalar_rgb: the wheels whole are over the device's 64 MiB) into $DIR. Then on the device
# machine, from the repository root, with $DIR and the Vulkan loader's .debs in .gl/ carried
# (device README): `bash tests/bench/peer_optix.sh`.
# usage: [SC="spheres-1m grass-1m ..."] [DIR=.mi] bash tests/bench/peer_optix.sh [pack]
set -uo pipefail
DIR=${DIR:-.mi}
SC=${SC:-"spheres-1m grass-1m shell-1m rocks-1m city-1m"}
if [ "${1:-}" = pack ]; then
  mkdir -p "$DIR" && site=$(mktemp -d) && mkdir "$site/site" || exit 1
  python3 -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 \
    --implementation cp --platform manylinux_2_28_x86_64 -d "$site/wheels" \
    mitsuba==3.9.1 drjit==1.5.0 || exit 1
  for w in "$site"/wheels/*.whl; do unzip -qo "$w" -d "$site/site"; done
  find "$site/site/mitsuba" -maxdepth 1 -name '*.cpython-*.so' | grep -E '/(scalar|llvm|cuda)_' |
    grep -vE '/(cuda_ad_rgb|scalar_rgb)\.' | xargs rm -f
  tar cJf "$DIR/site.tar.xz" -C "$site" site && rm -rf "$site"
  for b in runner examples/dump_ao; do
    strip -o "$DIR/tmp" "${CARGO_TARGET_DIR:-target}/release/$b" && xz -9c "$DIR/tmp" > "$DIR/${b#examples/}.xz"
  done
  rm -f "$DIR/tmp" && ls -la "$DIR"
  exit
fi
. tests/bench/device_env.sh
for b in runner dump_ao; do xz -dc "$DIR/$b.xz" > "/tmp/$b" && chmod +x "/tmp/$b"; done
tar xJf "$DIR/site.tar.xz" -C /tmp && export PYTHONPATH=/tmp/site
# Dr.Jit looks for the driver's CUDA and OptiX libraries by name; the device machine keeps
# them under /usr/local/nvidia.
lib() { find /usr/local/nvidia /usr/lib /usr/lib64 -name "$1" 2>/dev/null | head -1; }
c=$(lib 'libcuda.so.1') && [ -n "$c" ] && export DRJIT_LIBCUDA_PATH=${DRJIT_LIBCUDA_PATH:-$c}
o=$(lib 'libnvoptix.so.1') && [ -n "$o" ] && export DRJIT_LIBOPTIX_PATH=${DRJIT_LIBOPTIX_PATH:-$o}
echo "CUDA: ${DRJIT_LIBCUDA_PATH:-not found}, OptiX: ${DRJIT_LIBOPTIX_PATH:-not found}"
nvidia-smi --query-gpu=name,clocks.sm --format=csv,noheader
frame="--width 1920 --height 1080 --integrator ao --spp 1 --ao-rays 64 --bvh-quality high"
for s in $SC; do
  /tmp/dump_ao "/tmp/$s" --scene "$s" $frame 2>&1 | tail -1
  python3 tests/bench/peer_optix.py "/tmp/$s"
  echo "ours $s: $(/tmp/runner bench --backend gpu --scene "$s" $frame --runs 5 --warmup 3 2>&1 |
    grep -iE 'frame|rays/s' | tr '\n' ' ')"
  rm -rf "/tmp/$s"
done
