#!/usr/bin/env bash
# Cross-compiles occmap's core libraries and their tests for aarch64 (64-bit Arm Linux) with
# Debian's cross toolchain and runs the tests under qemu-user. Idempotent: installs what is
# missing, reuses the sysroot and the build.
#
#   bash scripts/check-aarch64.sh            # install, build build/aarch64, run the core suites
#   OCCMAP_AARCH64_TESTS='Fusion|Lut' bash scripts/check-aarch64.sh   # a ctest -R filter
#
# What it does, and why this way:
#  1. apt: g++-aarch64-linux-gnu and qemu-user (amd64 packages; nothing else changes).
#  2. The arm64 libraries (OpenCV core/imgproc/imgcodecs/calib3d/video, yaml-cpp, fmt,
#     GoogleTest, Eigen and what they need: ~190 packages, 120 MB) are downloaded with
#     `apt-get download` (dpkg --add-architecture arm64 for the package lists) and unpacked
#     into a private sysroot, NOT installed: installing them as multiarch packages would make
#     apt remove amd64 ones (libopencv-dev and libyaml-cpp-dev are not Multi-Arch: same, and
#     their arm64 dependencies pull newer amd64 versions of ~80 shared libraries, libgdal32
#     among the packages apt then removes).
#  3. cmake/aarch64-linux-gnu.cmake, OCCMAP_CORE_ONLY=ON (util, geometry, lut, detect, fusion,
#     objects, track: the rest needs FFmpeg, MQTT and the web bundle), no x86 kernels exist
#     there (util/simd.h), so every fast path runs its portable code.
#  4. ctest, each test binary under qemu-aarch64 -L SYSROOT (CMAKE_CROSSCOMPILING_EMULATOR).
set -euo pipefail
cd "$(dirname "$0")/.."
source_dir=$(pwd)
cache=${OCCMAP_AARCH64_CACHE:-$HOME/.cache/occmap-aarch64}
sysroot=$cache/sysroot
build=${OCCMAP_AARCH64_BUILD:-$source_dir/build/aarch64}
jobs=${OCCMAP_JOBS:-2}
apt_get() { DEBIAN_FRONTEND=noninteractive apt-get "$@"; }

# 1. Cross toolchain and emulator.
if ! command -v aarch64-linux-gnu-g++ >/dev/null || ! command -v qemu-aarch64 >/dev/null; then
  apt_get update -q
  apt_get install -y --no-install-recommends g++-aarch64-linux-gnu qemu-user
fi

# 2. The arm64 sysroot (made once; delete $cache to remake it).
runtime="libopencv-core406 libopencv-imgproc406 libopencv-imgcodecs406 libopencv-calib3d406 libopencv-video406
  libyaml-cpp0.7 libfmt9 libstdc++6 libc6"
dev="libopencv-core-dev libopencv-imgproc-dev libopencv-imgcodecs-dev libopencv-calib3d-dev libopencv-video-dev
  libopencv-features2d-dev libopencv-flann-dev libyaml-cpp-dev libfmt-dev libgtest-dev libgmock-dev"
if [ ! -f "$sysroot/.complete" ]; then
  if ! dpkg --print-foreign-architectures | grep -qx arm64; then dpkg --add-architecture arm64; fi
  if [ -z "$(apt-cache policy libc6:arm64 | sed -n 's/ *Candidate: //p' | grep -v '(none)')" ]; then apt_get update -q; fi
  arm64() { for p in "$@"; do echo "$p:arm64"; done; }
  # The runtime closure; packages of architecture all (data, scripts) are not needed here.
  closure=$(apt-cache depends --recurse --no-recommends --no-suggests --no-conflicts --no-breaks --no-replaces \
    --no-enhances $(arm64 $runtime) | grep -v '^ ' | grep ':arm64' | tr -d '<>' | sort -u)
  arch=$(apt-cache show --no-all-versions $closure 2>/dev/null |
    awk '/^Package:/{p=$2} /^Architecture: arm64/{print p ":arm64"}' | sort -u)
  mkdir -p "$cache/debs"
  (cd "$cache/debs" && apt-get download $arch $(arm64 $dev) libeigen3-dev)
  rm -rf "$sysroot" && mkdir -p "$sysroot"
  for deb in "$cache"/debs/*.deb; do dpkg-deb -x "$deb" "$sysroot"; done
  # What update-alternatives would have linked (OpenCV's BLAS and LAPACK).
  lib=$sysroot/usr/lib/aarch64-linux-gnu
  for alt in blas/libblas.so.3 lapack/liblapack.so.3; do
    [ -e "$lib/$(basename $alt)" ] || ln -s "$alt" "$lib/$(basename $alt)"
  done
  touch "$sysroot/.complete"
fi

# 3. Configure and build.
cmake -S "$source_dir" -B "$build" -G Ninja -DCMAKE_TOOLCHAIN_FILE="$source_dir/cmake/aarch64-linux-gnu.cmake" \
  -DOCCMAP_AARCH64_SYSROOT="$sysroot" -DCMAKE_BUILD_TYPE=Release -DOCCMAP_CORE_ONLY=ON -DOCCMAP_PYTHON=OFF \
  -DOCCMAP_WERROR=ON -DOCCMAP_DATASETS_DIR="$source_dir/../shared/datasets" >/dev/null
nice -n 19 cmake --build "$build" -j "$jobs"

# 4. The core suites under qemu-user.
nice -n 19 ctest --test-dir "$build" -j "$jobs" --timeout 1800 --output-on-failure ${OCCMAP_AARCH64_TESTS:+-R "$OCCMAP_AARCH64_TESTS"}
