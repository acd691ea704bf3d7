#!/usr/bin/env bash
# scripts/compare-outputs.sh (issue 40's byte-identity check) on the lab: the same binary twice is
# identical; a binary whose detections differ by one byte is named DIFFERENT with the file, exit
# 1; bad use is exit 2.
#
#   tests/compare_outputs_test.sh OCCMAP_BINARY
set -uo pipefail
occmap=$(realpath "${1:?usage: compare_outputs_test.sh OCCMAP_BINARY}")
script="$(dirname "$0")/../scripts/compare-outputs.sh"
source "$(dirname "$0")/test_lib.sh"
tl_init

out=$(bash "$script" "$occmap" "$occmap" lab 2>&1)
code=$?
[ $code -eq 0 ] && [[ "$out" == *"lab: identical ("* ]] && ok || fail "same binary: exit $code: $out"

# occmap, then one byte of detections.jsonl's fifth line changed.
cat >"$work/tampered" <<SH
#!/usr/bin/env bash
"$occmap" "\$@"; rc=\$?
out=; prev=
for a in "\$@"; do [ "\$prev" = --out ] && out=\$a; prev=\$a; done
[ -n "\$out" ] && [ -f "\$out/detections.jsonl" ] && sed -i '5s/"frame"/"frame" /' "\$out/detections.jsonl"
exit \$rc
SH
chmod +x "$work/tampered"
out=$(bash "$script" "$occmap" "$work/tampered" lab 2>&1)
code=$?
[ $code -eq 1 ] && [[ "$out" == *"lab: DIFFERENT in 1 of "*"detections.jsonl"* ]] && ok || fail "tampered: exit $code: $out"

out=$(bash "$script" "$occmap" "$occmap" hall 2>&1)
code=$?
[ $code -eq 2 ] && [[ "$out" == *"scene 'hall': expected lab"* ]] && ok || fail "unknown scene: exit $code: $out"
out=$(bash "$script" "$occmap" "$work/none" 2>&1)
code=$?
[ $code -eq 2 ] && [[ "$out" == *"expected an occmap binary"* ]] && ok || fail "missing binary: exit $code: $out"

tl_finish compare_outputs
