#!/usr/bin/env bash
# The portable build (OCCMAP_X86_KERNELS=OFF) must hold no AVX code of ours: no instruction of
# occmap's own libraries and executable touches a ymm or zmm register. Usage: check_no_x86_simd.sh FILE...
set -euo pipefail
status=0
for f in "$@"; do
  n=$(objdump -d --no-show-raw-insn "$f" | grep -cE '%[yz]mm[0-9]' || true)
  if [ "$n" -ne 0 ]; then
    echo "$f: expected no AVX instructions (ymm/zmm), found $n, e.g.:"
    objdump -d --no-show-raw-insn "$f" | grep -E '%[yz]mm[0-9]' | head -3
    status=1
  fi
done
[ "$status" -eq 0 ] && echo "no AVX instructions in $# files"
exit $status
