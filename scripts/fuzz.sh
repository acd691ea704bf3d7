#!/usr/bin/env bash
# Runs every libFuzzer target of fuzz/ (the readers: site and scene YAML, OpenCV/GoPro/Tsai
# calibrations, the table cache, run outputs, ground truth; the protocol messages: the MQTT
# evidence of `occmap edge`, the protections `occmap fuse` sends the edges, the JSON bodies of
# `occmap serve`'s API) for SECONDS each (default 60), one after the other.
# Usage: scripts/fuzz.sh [SECONDS] [TARGET...] (all targets when none is named; builds only those run)
# Installs clang-14 and libclang-rt-14-dev when missing, builds the `fuzz` preset (clang,
# -fsanitize=fuzzer,address,undefined; build/fuzz, apart from the main build), seeds each
# target from its committed corpus fuzz/corpus/NAME and, at run time, from the shared datasets
# ($OCCMAP_DATASETS, default ../shared/datasets; never copied into the repository). The corpus
# a run grows stays in build/fuzz/corpus/NAME; crashes go to build/fuzz/artifacts/. A target with
# fuzz/dict/NAME.dict gets it (keys, and bracket runs that reach the nesting limit). Prints per
# target the executions, the coverage (libFuzzer's cov: edges, ft: features) and the verdict.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-60}
shift || true
all=(site_yaml scene_yaml opencv_calibration gopro_calibration tsai_calibration lut_file run_outputs ground_truth
  edge_message protection_message serve_api)
[ $# -gt 0 ] && targets=("$@") || targets=("${all[@]}")

missing=()
for p in clang-14 libclang-rt-14-dev; do
  [ "$(dpkg-query -W -f='${db:Status-Status}' "$p" 2>/dev/null || true)" = installed ] || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  SUDO=""
  [ "$(id -u)" -ne 0 ] && SUDO=sudo
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

# Only the targets to run: a run of one target does not wait for the build of all ten
# (OCCMAP_FUZZ_JOBS, default 2: the build's parallel jobs). OCCMAP_FUZZ_BUILD=0 skips the build,
# for runs beside a build of the next targets in build/fuzz (two builds in one tree collide).
if [ "${OCCMAP_FUZZ_BUILD:-1}" != 0 ]; then
  cmake --preset fuzz >/dev/null
  build_targets=()
  for t in "${targets[@]}"; do build_targets+=("occmap_${t}_fuzzer"); done
  cmake --build --preset fuzz -j"${OCCMAP_FUZZ_JOBS:-2}" --target "${build_targets[@]}"
fi

datasets=${OCCMAP_DATASETS:-../shared/datasets}
build=build/fuzz
# Per process: two runs of this script at once (different targets) do not share it.
seeds=$build/seeds-$$
trap 'rm -rf "$seeds"' EXIT
mkdir -p "$seeds" "$build/artifacts"
# Seeds from the datasets, made at run time (two-file calibrations joined at a NUL byte).
if [ -d "$datasets" ]; then
  mkdir -p "$seeds"/{opencv_calibration,gopro_calibration,tsai_calibration,ground_truth,site_yaml}
  for i in 1 2 3; do
    intr=$(ls "$datasets"/wildtrack/calibrations/intrinsic_zero/*"$i".xml 2>/dev/null | head -1 || true)
    extr=$(ls "$datasets"/wildtrack/calibrations/extrinsic/*"$i".xml 2>/dev/null | head -1 || true)
    [ -n "$intr" ] && [ -n "$extr" ] && { cat "$intr"; printf '\0'; cat "$extr"; } >"$seeds/opencv_calibration/wildtrack_$i"
  done
  for intr in "$datasets"/multiviewx/calibrations/intrinsic/*.xml; do
    [ -f "$intr" ] || continue
    extr="$datasets/multiviewx/calibrations/extrinsic/$(basename "$intr" | sed 's/^intr_/extr_/')"
    [ -f "$extr" ] && { cat "$intr"; printf '\0'; cat "$extr"; } >"$seeds/opencv_calibration/multiviewx_$(basename "$intr")"
  done
  for intr in "$datasets"/gopro4/calibration/intrinsics_*.json; do
    [ -f "$intr" ] || continue
    extr="$datasets/gopro4/calibration/$(basename "$intr" | sed 's/^intrinsics_/extrinsics_/')"
    [ -f "$extr" ] && { cat "$intr"; printf '\0'; cat "$extr"; } >"$seeds/gopro_calibration/$(basename "$intr")"
  done
  cp "$datasets"/tsai-terrace/*.yaml "$seeds/tsai_calibration/" 2>/dev/null || true
  # Not `ls | head`: ls killed by SIGPIPE fails the pipe, and set -e ended the script silently.
  gt=("$datasets"/wildtrack/annotations_positions/*.json)
  if [ -f "${gt[0]}" ]; then cp -t "$seeds/ground_truth/" "${gt[@]:0:20}"; fi
  cp sites/*.yaml "$seeds/site_yaml/"
fi

printf '%-20s %12s %8s %8s %8s  %s\n' target executions exec/s cov ft result
status=0
for t in "${targets[@]}"; do
  bin=$build/fuzz/occmap_${t}_fuzzer
  corpus=$build/corpus/$t
  mkdir -p "$corpus" "$seeds/$t"
  log=$build/$t.log
  set +e
  dict=()
  [ -f "fuzz/dict/$t.dict" ] && dict=(-dict="fuzz/dict/$t.dict")
  "$bin" "$corpus" "fuzz/corpus/$t" "$seeds/$t" "${dict[@]}" -max_total_time="$seconds" -print_final_stats=1 -rss_limit_mb=4096 \
    -timeout=20 -max_len=65536 -artifact_prefix="$build/artifacts/$t-" >"$log" 2>&1
  rc=$?
  set -e
  execs=$(grep -m1 'stat::number_of_executed_units' "$log" | awk '{print $2}')
  rate=$(grep -m1 'stat::average_exec_per_sec' "$log" | awk '{print $2}')
  cov=$(grep -E '^#[0-9]+' "$log" | grep -o 'cov: [0-9]*' | tail -1 | awk '{print $2}')
  ft=$(grep -E '^#[0-9]+' "$log" | grep -o 'ft: [0-9]*' | tail -1 | awk '{print $2}')
  if [ $rc -eq 0 ]; then verdict=ok; else verdict="FAILED (exit $rc, see $log)"; status=1; fi
  printf '%-20s %12s %8s %8s %8s  %s\n' "$t" "${execs:-?}" "${rate:-?}" "${cov:-?}" "${ft:-?}" "$verdict"
done
exit $status
