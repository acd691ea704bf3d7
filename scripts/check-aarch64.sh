#!/usr/bin/env bash
# Cross-compiles occmap for aarch64 (64-bit Arm Linux) with Debian's cross toolchain: the
# program and the core libraries' tests, runs the tests under qemu-user, then the program itself
# on a rendered scene beside the x86 build. Idempotent: installs what is missing, reuses the
# sysroot and the build.
#
#   bash scripts/check-aarch64.sh            # install, build build/aarch64, run the suites and the program
#   OCCMAP_AARCH64_TESTS='Fusion|Lut' bash scripts/check-aarch64.sh   # a ctest -R filter
#   OCCMAP_AARCH64_PROGRAM=0 bash scripts/check-aarch64.sh   # the core libraries and their tests only
#   OCCMAP_AARCH64_RUN=0 ...      # build the program and run the suites, not the program
#   OCCMAP_X86=PATH ...           # the x86 occmap to compare with (default build/release/occmap)
#
# What it does, and why this way:
#  1. apt: g++-aarch64-linux-gnu and qemu-user (amd64 packages; nothing else changes).
#  2. The arm64 libraries (OpenCV, FFmpeg, libmosquitto, cpp-httplib, yaml-cpp, fmt, GoogleTest,
#     Eigen, nlohmann-json, CLI11 and what they need: ~370 packages, 230 MB) are downloaded with
#     `apt-get download` (dpkg --add-architecture arm64 for the package lists) and unpacked
#     into a private sysroot, NOT installed: installing them as multiarch packages would make
#     apt remove amd64 ones (libopencv-dev and libyaml-cpp-dev are not Multi-Arch: same, and
#     their arm64 dependencies pull newer amd64 versions of ~80 shared libraries, libgdal32
#     among the packages apt then removes).
#  3. cmake/aarch64-linux-gnu.cmake (pkg-config pointed at the sysroot); no x86 kernels exist
#     there (util/simd.h), so every fast path runs its portable code. The web bundle (node, npm)
#     and the embedded assets (Python) are made by the host's tools. No Python module.
#  4. ctest: the core suites (util, geometry, lut, detect, fusion, objects, track), each test
#     binary under qemu-aarch64 -L SYSROOT (CMAKE_CROSSCOMPILING_EMULATOR).
#  5. The program under qemu-aarch64 (see there).
set -euo pipefail
cd "$(dirname "$0")/.."
source_dir=$(pwd)
cache=${OCCMAP_AARCH64_CACHE:-$HOME/.cache/occmap-aarch64}
sysroot=$cache/sysroot
build=${OCCMAP_AARCH64_BUILD:-$source_dir/build/aarch64}
jobs=${OCCMAP_JOBS:-2}
program=${OCCMAP_AARCH64_PROGRAM:-1}
apt_get() { DEBIAN_FRONTEND=noninteractive apt-get "$@"; }

# 1. Cross toolchain and emulator.
if ! command -v aarch64-linux-gnu-g++ >/dev/null || ! command -v qemu-aarch64 >/dev/null; then
  apt_get update -q
  apt_get install -y --no-install-recommends g++-aarch64-linux-gnu qemu-user
fi

# 2. The arm64 sysroot. Remade when the package lists below change (their hash is in .complete).
# One sysroot for both modes (the program's libraries added: ~xx packages, xx MB more).
runtime="libopencv-core406 libopencv-imgproc406 libopencv-imgcodecs406 libopencv-calib3d406 libopencv-video406
  libyaml-cpp0.7 libfmt9 libstdc++6 libc6
  libavcodec59 libavformat59 libavutil57 libswscale6 libavdevice59 libmosquitto1 libcpp-httplib0.11"
# Downloaded without their dependencies: headers, .pc files, CMake packages. libopencv-contrib406
# (ArUco) too: its closure is Qt 5, Tesseract and HDF5, while libopencv_aruco needs only
# calib3d, imgproc and core. pkg-config reads the .pc files of FFmpeg's and cpp-httplib's
# private requirements (libavfilter, openssl, zlib, brotli) for the flags.
dev="libopencv-core-dev libopencv-imgproc-dev libopencv-imgcodecs-dev libopencv-calib3d-dev libopencv-video-dev
  libopencv-features2d-dev libopencv-flann-dev libyaml-cpp-dev libfmt-dev libgtest-dev libgmock-dev
  libopencv-contrib406 libopencv-contrib-dev libavcodec-dev libavformat-dev libavutil-dev libswscale-dev
  libavdevice-dev libavfilter-dev libswresample-dev libpostproc-dev libmosquitto-dev libcpp-httplib-dev
  libssl-dev zlib1g-dev libbrotli-dev"
# Architecture all: the same files on every architecture.
indep="libeigen3-dev nlohmann-json3-dev libcli11-dev"
lists_hash=$(echo $runtime / $dev / $indep | sha256sum | cut -c1-16)
if [ "$(cat "$sysroot/.complete" 2>/dev/null)" != "$lists_hash" ]; then
  if ! dpkg --print-foreign-architectures | grep -qx arm64; then dpkg --add-architecture arm64; fi
  if [ -z "$(apt-cache policy libc6:arm64 | sed -n 's/ *Candidate: //p' | grep -v '(none)')" ]; then apt_get update -q; fi
  arm64() { for p in "$@"; do echo "$p:arm64"; done; }
  # The runtime closure; packages of architecture all (data, scripts) are not needed here.
  closure=$(apt-cache depends --recurse --no-recommends --no-suggests --no-conflicts --no-breaks --no-replaces \
    --no-enhances $(arm64 $runtime) | grep -v '^ ' | grep ':arm64' | tr -d '<>' | sort -u)
  arch=$(apt-cache show --no-all-versions $closure 2>/dev/null |
    awk '/^Package:/{p=$2} /^Architecture: arm64/{print p ":arm64"}' | sort -u)
  rm -rf "$cache/debs" && mkdir -p "$cache/debs"
  (cd "$cache/debs" && apt-get download $arch $(arm64 $dev) $indep)
  rm -rf "$sysroot" && mkdir -p "$sysroot"
  for deb in "$cache"/debs/*.deb; do dpkg-deb -x "$deb" "$sysroot"; done
  # What update-alternatives would have linked (OpenCV's BLAS and LAPACK).
  lib=$sysroot/usr/lib/aarch64-linux-gnu
  for alt in blas/libblas.so.3 lapack/liblapack.so.3; do
    [ -e "$lib/$(basename $alt)" ] || ln -s "$alt" "$lib/$(basename $alt)"
  done
  echo "$lists_hash" > "$sysroot/.complete"
fi

# 3. Configure and build: the program and the core suites, or (OCCMAP_AARCH64_PROGRAM=0) the
# core libraries alone. Node, npm and Python are the host's (CMAKE_FIND_ROOT_PATH_MODE_PROGRAM
# NEVER): the web bundle is built and embedded on the host, as in a native build.
core_tests="occmap_util_test occmap_geometry_test occmap_lut_test occmap_detect_test occmap_fusion_test
  occmap_objects_test occmap_track_test"
if [ "$program" = 1 ]; then core_only=OFF; targets="occmap $core_tests"; else core_only=ON; targets=$core_tests; fi
start=$SECONDS
# The toolchain file's linker flags are read into a new cache only.
[ "$build/CMakeCache.txt" -nt cmake/aarch64-linux-gnu.cmake ] || rm -f "$build/CMakeCache.txt"
cmake -S "$source_dir" -B "$build" -G Ninja -DCMAKE_TOOLCHAIN_FILE="$source_dir/cmake/aarch64-linux-gnu.cmake" \
  -DOCCMAP_AARCH64_SYSROOT="$sysroot" -DCMAKE_BUILD_TYPE=Release -DOCCMAP_CORE_ONLY=$core_only -DOCCMAP_PYTHON=OFF \
  -DOCCMAP_WERROR=ON -DOCCMAP_DATASETS_DIR="$source_dir/../shared/datasets" >/dev/null
nice -n 19 cmake --build "$build" -j "$jobs" --target $targets ${OCCMAP_AARCH64_TARGETS:-}
echo "check-aarch64: build $((SECONDS - start)) s"

# 4. The core suites under qemu-user (the unit tests of the targets built; the program's own
# tests are shell and Python scripts that run the binary directly: step 5 stands for them).
start=$SECONDS
suites=0
nice -n 19 ctest --test-dir "$build" -j "$jobs" --timeout 1800 --output-on-failure -L unit \
  -E '_NOT_BUILT$|^occmap_fuzz_corpus_' ${OCCMAP_AARCH64_TESTS:+-R "$OCCMAP_AARCH64_TESTS"} || suites=1
echo "check-aarch64: core suites $((SECONDS - start)) s"
[ "$program" = 1 ] && [ "${OCCMAP_AARCH64_RUN:-1}" = 1 ] || exit $suites

# 5. The program under qemu-user on the lab scene (4 cameras, 20 frames, H.264 encoded and decoded
# on arm64): --version, synth, run, eval, serve (its web page and API); the x86 build's run on
# the same videos with the portable kernels (OCCMAP_KERNELS=portable), whose outputs must equal
# Arm's byte for byte; and the deployment of issue 17, an Arm `occmap edge` publishing to a host
# mosquitto and an x86 `occmap fuse`, whose outputs must equal the run's. The x86 parts need
# OCCMAP_X86 (default build/release/occmap) and mosquitto; they are skipped without them.
set +e
source "$source_dir/tests/test_lib.sh"
tl_init
lib=$sysroot/usr/lib/aarch64-linux-gnu
ld_path="$lib:$sysroot/lib/aarch64-linux-gnu:$sysroot/usr/lib:$lib/pulseaudio"
arm="$work/occmap-arm"
printf '#!/bin/sh\nexec nice -n 19 qemu-aarch64 -L "%s" -E "LD_LIBRARY_PATH=%s" "%s" "$@"\n' \
  "$sysroot" "$ld_path" "$build/occmap" >"$arm"
chmod +x "$arm"
x86=${OCCMAP_X86:-$source_dir/build/release/occmap}
exec 3>&1  # the timings, while the commands' output goes to their logs
timed() {  # timed WHAT COMMAND...
  local t=$SECONDS what=$1 code
  shift
  "$@"
  code=$?
  echo "check-aarch64: $((SECONDS - t)) s: $what" >&3
  return $code
}
outputs="detections.jsonl tracks.jsonl tracks_mot.csv"
same_outputs() {  # same_outputs DIR_A DIR_B WHAT
  local f
  for f in $outputs; do
    if [ -s "$1/$f" ] && cmp -s "$1/$f" "$2/$f"; then
      ok
    else
      fail "$3: $f differs ($(lines "$1/$f") vs $(lines "$2/$f") lines)"
    fi
  done
}
moda() {
  "$python" -c "import json, sys; print(json.load(open(sys.argv[1]))['detection']['moda'])" "$1/evaluation.json" 2>/dev/null
}

version=$("$arm" --version 2>&1) && [ -n "$version" ] && ok || fail "occmap --version: $version"
echo "check-aarch64: occmap --version: $version ($(file -b "$build/occmap" | cut -d, -f1-2))"
common=(--no-cache --threads 2)
timed "aarch64 synth" "$arm" synth --scene lab --frames 20 --video --out "$work/lab" >"$work/synth.log" 2>&1 ||
  { fail "occmap synth: $(tail -2 "$work/synth.log")"; tl_finish check-aarch64; exit 1; }
timed "aarch64 run" "$arm" run "$work/lab/site.yaml" --out "$work/arm-run" --no-wall-clock --occupancy-pngs \
  "${common[@]}" >"$work/arm-run.log" 2>&1 &&
  ok || fail "occmap run: $(tail -2 "$work/arm-run.log")"
[ -s "$work/arm-run/mosaic.mp4" ] && ok || fail "occmap run wrote no mosaic.mp4"
"$arm" eval "$work/lab" "$work/arm-run" >"$work/arm-eval.log" 2>&1 && ok ||
  fail "occmap eval: $(tail -2 "$work/arm-eval.log")"
echo "check-aarch64: aarch64 MODA $(moda "$work/arm-run")"
# `occmap serve`: the embedded web bundle as built on the host, the API, a clean SIGTERM.
"$arm" serve "$work/lab/site.yaml" --listen 127.0.0.1:0 --out "$work/serve" --no-video "${common[@]}" \
  >"$work/serve.log" 2>&1 &
serve_pid=$!
tl_track $serve_pid
tl_wait_for "$work/serve.log" "listening on" 60
port=$(sed -n 's#.*listening on http://127.0.0.1:\([0-9]*\)/.*#\1#p' "$work/serve.log" | head -1)
for page in index.html app.js; do
  curl -sf "http://127.0.0.1:$port/${page#index.html}" | cmp -s - "$build/web-dist/$page" && ok ||
    fail "occmap serve: /$page is not web-dist's ($(tail -2 "$work/serve.log"))"
done
curl -sf "http://127.0.0.1:$port/api/site" | grep -q '"id":"cam4"' && ok || fail "occmap serve: /api/site has no cam4"
kill -TERM $serve_pid
wait $serve_pid && ok || fail "occmap serve: exit $? at SIGTERM: $(tail -2 "$work/serve.log")"

if [ -x "$x86" ]; then
  OCCMAP_KERNELS=portable timed "x86 run" "$x86" run "$work/lab/site.yaml" --out "$work/x86-run" --no-wall-clock \
    --occupancy-pngs "${common[@]}" >"$work/x86-run.log" 2>&1 &&
    ok || fail "x86 occmap run: $(tail -2 "$work/x86-run.log")"
  "$x86" eval "$work/lab" "$work/x86-run" >/dev/null 2>&1
  echo "check-aarch64: x86 (portable kernels) MODA $(moda "$work/x86-run")"
  same_outputs "$work/x86-run" "$work/arm-run" "aarch64 run against x86 run"
  diff -rq "$work/x86-run/occupancy" "$work/arm-run/occupancy" >/dev/null && ok ||
    fail "aarch64 run against x86 run: the occupancy maps (occupancy/*.png) differ"

  if command -v /usr/sbin/mosquitto >/dev/null && command -v mosquitto_pub >/dev/null; then
    tl_broker
    broker="mqtt://127.0.0.1:$broker_port"
    "$x86" fuse "$work/lab/site.yaml" --broker "$broker" --out "$work/fuse" --no-video --no-wall-clock \
      --latency-budget-s 600 --dead-after-s 600 "${common[@]}" >"$work/fuse.log" 2>&1 &
    fuse_pid=$!
    tl_track $fuse_pid
    tl_wait_for "$work/fuse.log" "subscribed to" 10
    t=$SECONDS
    "$arm" edge "$work/lab/site.yaml" --cameras cam1,cam2,cam3,cam4 --broker "$broker" "${common[@]}" \
      >"$work/edge-arm.log" 2>&1 &
    edge_pid=$!
    tl_track $edge_pid
    tl_edges_then_fuse $fuse_pid "$work/fuse.log" 60 $edge_pid
    echo "check-aarch64: $((SECONDS - t)) s: aarch64 edge -> x86 fuse"
    same_outputs "$work/x86-run" "$work/fuse" "x86 fuse of the aarch64 edge against x86 run"
  else
    echo "check-aarch64: SKIP the edge -> fuse check: no mosquitto (scripts/install-deps.sh installs it)"
  fi
else
  echo "check-aarch64: SKIP the comparisons with x86: no $x86 (cmake --build --preset release --target occmap)"
fi
tl_finish check-aarch64 && exit $suites
