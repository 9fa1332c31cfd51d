#!/usr/bin/env bash
# The panics left in the kernels after optimisation, by source line, with how many copies
# of each the module holds: rust-gpu makes each a return from the kernel, which costs the
# loops around it (docs/PERFORMANCE.md, "Panics in the walk's loop"). Builds the kernels
# with RT_SHADER_PANICS=report (runner/build.rs), whose SPIR-V keeps each panic's line as
# a string (the next build without it rebuilds the kernels as usual). Run it from the
# repository root; CARGO_TARGET_DIR is honoured. Each line: how many times the module
# holds it (once per kernel it is inlined into, or more), then the panic's source line.
# usage: bash tests/bench/panic_sites.sh [PATTERN]   (PATTERN: a grep on the lines, e.g. bvh.rs)
set -euo pipefail
target=${CARGO_TARGET_DIR:-target}
RT_SHADER_PANICS=report cargo build --release -p runner >&2
spv=$(ls -t $(find "$target/spirv-builder" -name kernels.spv) | head -1)
strings -n 8 "$spv" | grep -o 'panicked at [^]]*' | sed 's/^panicked at //' | grep -e "${1:-.}" \
  | sort | uniq -c | sort -rn
