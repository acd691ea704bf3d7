#!/usr/bin/env bash
# The installed occmap: `cmake --install` into a scratch prefix (headers closed under #include and
# free of test hooks, the CMake package, the Python module, the manual page), a consumer project built against it
# with find_package(occmap) (docs/cpp.md), and `cpack -G DEB` unpacked with dpkg -x
# into a scratch root whose occmap runs the demo.
# Usage: install_test.sh BUILD_DIR SOURCE_DIR DATASETS_DIR PYTHON
set -euo pipefail
build=$(cd "$1" && pwd); src=$(cd "$2" && pwd); datasets=$3; python=${4:-python3}
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

cmake --install "$build" --prefix "$tmp/prefix" >/dev/null
inc="$tmp/prefix/include"
[ -f "$inc/occmap/pipeline/run.h" ] || fail "run.h not installed"
# Every occmap include of an installed header is installed; no internal header or test hook is.
while IFS= read -r h; do
  for dep in $(grep -o '#include "occmap/[^"]*"' "$h" | sed 's/#include "\(.*\)"/\1/'); do
    [ -f "$inc/$dep" ] || fail "$h includes $dep, which is not installed"
  done
done < <(find "$inc/occmap" -name '*.h')
if grep -rl "ForTesting" "$inc/occmap"; then fail "a test hook is in the installed headers"; fi
for internal in fusion/fast_fusion.h objects/split_internal.h pipeline/frame_set.h util/testing.h; do
  [ ! -e "$inc/occmap/$internal" ] || fail "internal header $internal installed"
done
[ -f "$tmp/prefix/lib/"*/cmake/occmap/occmapConfig.cmake ] || [ -f "$tmp/prefix/lib/cmake/occmap/occmapConfig.cmake" ] \
  || fail "no occmapConfig.cmake"
[ -x "$tmp/prefix/bin/occmap" ] || fail "occmap program not installed"
[ -f "$tmp/prefix/share/occmap/sites/gopro4.yaml" ] || fail "sites not installed"
# The manual page: a section for every command of --help, nothing groff warns about.
man1="$tmp/prefix/share/man/man1/occmap.1.gz"
[ -f "$man1" ] || fail "occmap.1.gz not installed"
commands=$("$tmp/prefix/bin/occmap" --help | sed -n '/^Subcommands:/,$p' | awk '/^  [a-z]/ {print $1}')
[ -n "$commands" ] || fail "occmap --help lists no commands"
for c in $commands; do
  # roff escapes a hyphen: edge-sim is written edge\-sim.
  zcat "$man1" | grep -qxF ".SS ${c//-/\\-}" || fail "the manual page has no section for the command $c"
done
if command -v groff >/dev/null; then
  warnings=$(zcat "$man1" | groff -man -Tutf8 -ww -z 2>&1)
  [ -z "$warnings" ] || fail "groff on the manual page: $warnings"
fi

# The consumer project.
cmake -S "$src/tests/install/consumer" -B "$tmp/consumer" -G Ninja -DCMAKE_PREFIX_PATH="$tmp/prefix" \
  -DCMAKE_BUILD_TYPE=Release >/dev/null
nice -n 10 cmake --build "$tmp/consumer" -j2 >/dev/null
if [ -d "$datasets/gopro4" ]; then
  out=$("$tmp/consumer/count_people" "$tmp/prefix/share/occmap/sites/gopro4.yaml" "$datasets")
  echo "consumer: $out"
  [ "$out" = "1 frames, at most 4 people in a frame" ] || fail "consumer printed '$out'"
fi
set +e
"$tmp/consumer/count_people" "$tmp/missing.yaml" 2>"$tmp/err"; code=$?
set -e
[ $code -eq 2 ] && grep -q "missing.yaml" "$tmp/err" || fail "consumer on a missing site: exit $code"

# docs/cpp.md's example, its two blocks exactly as printed, under the compiler's default
# standard: occmap::occmap must bring C++20 itself.
mkdir -p "$tmp/readme"
awk '/^# Use from C\+\+/ {on = 1} on && /^```cmake$/ {f = "CMakeLists.txt"; next} on && /^```cpp$/ {f = "main.cc"; next}
     on && /^```$/ {if (f == "main.cc") exit; f = ""; next} f != "" {print > (dir "/" f)}' dir="$tmp/readme" "$src/docs/cpp.md"
[ -s "$tmp/readme/CMakeLists.txt" ] && [ -s "$tmp/readme/main.cc" ] || fail "docs/cpp.md's C++ example not found"
cmake -S "$tmp/readme" -B "$tmp/readme/build" -G Ninja -DCMAKE_PREFIX_PATH="$tmp/prefix" -DCMAKE_BUILD_TYPE=Release \
  >"$tmp/readme.log" 2>&1 || { cat "$tmp/readme.log"; fail "docs/cpp.md's CMakeLists.txt does not configure"; }
nice -n 10 cmake --build "$tmp/readme/build" -j2 >>"$tmp/readme.log" 2>&1 \
  || { tail -30 "$tmp/readme.log"; fail "docs/cpp.md's example does not build"; }
set +e
"$tmp/readme/build/count_people" "$tmp/missing.yaml" 2>"$tmp/err"; code=$?
set -e
[ $code -eq 2 ] && grep -q "missing.yaml" "$tmp/err" || fail "docs/cpp.md's example on a missing site: exit $code"

# The Python module from the installed tree.
if [ -d "$tmp/prefix/lib/python3/dist-packages/occmap" ]; then
  where=$(cd "$tmp" && PYTHONPATH="$tmp/prefix/lib/python3/dist-packages" "$python" -c \
    'import occmap; print(occmap.__file__); occmap.Grid((0, 0), (4, 3), 0.5)')
  case "$where" in "$tmp/prefix/"*) ;; *) fail "python imported occmap from $where" ;; esac
fi

# The Debian package, unpacked (dpkg -x) into a scratch root.
(cd "$tmp" && cpack -G DEB --config "$build/CPackConfig.cmake" -B "$tmp/pkg" >/dev/null)
deb=$(ls "$tmp"/pkg/occmap_*.deb)
deps=$(dpkg-deb -f "$deb" Depends)
echo "package: $(basename "$deb"), depends: $deps"
for lib in libopencv libyaml-cpp libavcodec libmosquitto libfmt; do
  grep -q "$lib" <<<"$deps" || fail "Depends lacks $lib"
done
dpkg -x "$deb" "$tmp/root"
[ -f "$tmp/root/usr/share/man/man1/occmap.1.gz" ] || fail "the package has no occmap.1.gz"
"$tmp/root/usr/bin/occmap" --help | grep -q "demo" || fail "--help"
# The module where Debian's python3 looks (/usr/lib/python3/dist-packages), importable by it.
if [ -d "$tmp/prefix/lib/python3/dist-packages/occmap" ] && [ -x /usr/bin/python3 ]; then
  ls "$tmp/root/usr/lib/python3/dist-packages/occmap/"_occmap*.so >/dev/null 2>&1 \
    || fail "the package has no occmap module in /usr/lib/python3/dist-packages"
  version=$(cd "$tmp" && PYTHONPATH="$tmp/root/usr/lib/python3/dist-packages" /usr/bin/python3 -c \
    'import occmap; print(occmap.__version__)') || fail "Debian's python3 cannot import the package's occmap"
  [ "$version" = "$(dpkg-deb -f "$deb" Version)" ] || fail "occmap.__version__ '$version' is not the package's"
fi
(cd "$tmp" && "$tmp/root/usr/bin/occmap" --threads 2 demo --frames 10 --out "$tmp/demo" >"$tmp/demo.log") || fail "occmap demo from the package"
[ -f "$tmp/demo/summary.json" ] || [ -n "$(ls "$tmp/demo")" ] || fail "demo wrote nothing"
echo "install test passed"
