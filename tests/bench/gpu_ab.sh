#!/usr/bin/env bash
# The README's GPU A/B tables: GPU ms per frame of several runner builds (or one build under
# several environments), each workload run by every variant in turn, the variants' order
# reversed every other round, so that a clock drop or a warm cache favours none of them.
# Run it on the device machine from the repository root, the binaries built elsewhere as
# $DIR/runner-NAME.xz (strip + xz), the Vulkan loader's .debs in .gl/ (device README).
# Each line: round, workload, variant, median GPU ms per frame, the BVH build time; at the
# end, each workload and variant's mean over the rounds.
# usage: VARS="old new new:SOME_ENV=1 new@--ao-order=near" [W="ao-rocks mis-cornell ..."] \
#        [ROUNDS=2] [DIR=.dev] bash tests/bench/gpu_ab.sh
# A variant is NAME (runner-NAME), NAME:VAR=VALUE[,VAR=VALUE...] (that build with those set) or NAME@ARG
# (that build with one more bench argument). A workload is one of the names in args() below,
# or KIND:SCENE (KIND ao, nee, mis or pt as below, at --bvh-quality high unless the variant
# says otherwise, on any scene).
set -uo pipefail
DIR=${DIR:-.dev}
. tests/bench/device_env.sh
build() { local b=${1%%@*}; echo "${b%%:*}"; }
for v in $VARS; do
  b=$DIR/runner-$(build "$v")
  [ -x "$b" ] || { xz -dkf "$b.xz" && chmod +x "$b"; }
done
nvidia-smi --query-gpu=name,clocks.sm --format=csv,noheader
args() { case $1 in
  ao:*) echo "--integrator ao --spp 1 --ao-rays 64 $quality --scene ${1#*:}" ;;
  nee:*) echo "--integrator nee --max-depth 2 --spp 1 $quality --scene ${1#*:}" ;;
  mis:*) echo "--integrator mis --max-depth 8 --spp 1 $quality --scene ${1#*:}" ;;
  pt:*) echo "--integrator pt --max-depth 8 --spp 1 $quality --scene ${1#*:}" ;;
  ao-cornell) echo "--integrator ao --spp 1 --ao-rays 64 --scene cornell-box" ;;
  mis-cornell) echo "--integrator mis --max-depth 8 --spp 1 --bvh-splits 0 --scene cornell-box" ;;
  nee-many) echo "--integrator nee --max-depth 2 --spp 1 --bvh-splits 0 --scene many-lights" ;;
  restir-many) echo "--integrator restir --max-depth 2 --spp 1 --bvh-splits 0 --scene many-lights" ;;
  # textured_scene.py's terrain (colour + normal map, rough metal, sky.hdr): texture lookups
  # on every path. Its files come as $DIR/textured.tar.xz (too large to carry unpacked).
  mis-terrain | pt-terrain) echo "--integrator ${1%%-*} --max-depth 8 --spp 1 $(terrain)" ;;
  # KIND-NAME: KIND:NAME-1m, a suite scene
  ao-* | nee-* | pt-*) args "${1%%-*}:${1#*-}-1m" ;;
  *) echo "unknown workload $1" >&2; exit 2 ;;
esac; }
terrain() {
  local t=$DIR/textured
  [ -f "$t/terrain.obj" ] || tar -xJf "$t.tar.xz" -C "$DIR" || exit 2
  echo "--scene $t/terrain.obj --env $t/sky.hdr --eye 0,7,13 --target 0,0,0"
}
bench() { # variant workload
  local v=$1 b env=() extra=()
  b=$(build "$v")
  [[ $v == *@* ]] && extra=("${v#*@}")
  # KIND:SCENE builds at high, unless the variant's argument chooses (NAME@--bvh-quality=auto)
  local quality="--bvh-quality high"
  [[ ${extra[*]:-} == --bvh-quality* ]] && quality=""
  local rest=${v%%@*}
  [[ $rest == *:* ]] && IFS=, read -ra env <<<"${rest#*:}"
  out=$(env "${env[@]}" "$DIR/runner-$b" bench --backend gpu --width 1920 --height 1080 \
    --runs 5 --warmup 3 $(args "$2") "${extra[@]}" 2>&1)
  ms=$(echo "$out" | awk '/^ms\/frame/{print $5}')
  # the BVH's build time after the ms, for the tables' build column
  echo "r$round $2 $v ${ms:-FAILED} $(echo "$out" | grep -o 'build [0-9.]* ms')"
  results+=("$2 $v ${ms:-FAILED}")
  [ -z "$ms" ] && echo "$out" | tail -5
}
W=${W:-"ao-cornell ao-rocks ao-spheres ao-city ao-grass ao-shell mis-cornell nee-many"}
rev=""; for v in $VARS; do rev="$v $rev"; done
results=()
for round in $(seq "${ROUNDS:-2}"); do
  order=$VARS; [ $((round % 2)) = 0 ] && order=$rev
  for w in $W; do for v in $order; do bench "$v" "$w"; done; done
done
# The means over the rounds, in the order first run: what the tables quote.
echo "means over ${ROUNDS:-2} rounds, ms:"
printf '%s\n' "${results[@]}" | awk '$3 != "FAILED" {
  k = $1 " " $2; if (!(k in n)) order[++keys] = k; s[k] += $3; n[k]++ }
  END { for (i = 1; i <= keys; i++) printf "%s %.3f\n", order[i], s[order[i]] / n[order[i]] }'
