#!/usr/bin/env bash
# Are two builds' outputs byte-identical? For a refactoring or a fast path that must not change
# what occmap finds: both binaries run the same inputs and every output that depends on the
# inputs alone is compared byte for byte (`--no-wall-clock`: no t_unix; summary.json and the
# videos hold timings and are left out).
#
#   scripts/compare-outputs.sh OLD_OCCMAP NEW_OCCMAP [SCENE...]
#
# Scenes (default all): lab (rendered, 60 frames, tracks and events), plaza (rendered at 0.25,
# 120 frames, backgrounds learned and settled), wildtrack (rendered from the real calibration at
# 0.25, 20 frames, the people detector), gopro4 (the real masks of ../shared/datasets/gopro4),
# edge (the lab through 2 edges and a fuse over a mosquitto of the script's own). The scenes are
# rendered once, by NEW. A scene whose data or program is missing is skipped, with a message.
# Prints one line a scene; exit 0 when every scene run is identical, 1 when one differs (the
# files named), 2 on bad use. OCCMAP_COMPARE_KEEP=DIR keeps the work folder in DIR.
set -uo pipefail
usage() { echo "usage: compare-outputs.sh OLD_OCCMAP NEW_OCCMAP [lab|plaza|wildtrack|gopro4|edge ...]" >&2; exit 2; }
[ $# -ge 2 ] || usage
old=$(realpath "$1" 2>/dev/null) && [ -x "$old" ] || { echo "compare-outputs: $1: expected an occmap binary" >&2; exit 2; }
new=$(realpath "$2" 2>/dev/null) && [ -x "$new" ] || { echo "compare-outputs: $2: expected an occmap binary" >&2; exit 2; }
shift 2
scenes=("$@")
[ ${#scenes[@]} -gt 0 ] || scenes=(lab plaza wildtrack gopro4 edge)
for s in "${scenes[@]}"; do
  case $s in lab | plaza | wildtrack | gopro4 | edge) ;; *) echo "compare-outputs: scene '$s': expected lab, plaza, wildtrack, gopro4 or edge" >&2; exit 2 ;; esac
done
repo=$(cd "$(dirname "$0")/.." && pwd)
datasets="$repo/../shared/datasets"
source "$repo/tests/test_lib.sh"
tl_init
if [ -n "${OCCMAP_COMPARE_KEEP:-}" ]; then
  rm -rf "$work"
  mkdir -p "$OCCMAP_COMPARE_KEEP" && work=$(realpath "$OCCMAP_COMPARE_KEEP")
  trap 'work=; tl_cleanup' EXIT
fi
differ=0

# compare NAME DIR_OLD DIR_NEW: every output file of either run but the timed ones, byte for byte.
compare() {
  local name=$1 a=$2 b=$3 f files=() bad=()
  while IFS= read -r f; do files+=("$f"); done < <(
    { (cd "$a" && find . -type f); (cd "$b" && find . -type f); } |
      grep -vE '^\./(summary\.json|[^/]*\.mp4)$' | sort -u)
  for f in "${files[@]}"; do cmp -s "$a/$f" "$b/$f" || bad+=("${f#./}"); done
  if [ ${#files[@]} -eq 0 ]; then
    echo "$name: no outputs to compare ($a, $b)"
    differ=1
  elif [ ${#bad[@]} -eq 0 ]; then
    echo "$name: identical (${#files[@]} files)"
  else
    echo "$name: DIFFERENT in ${#bad[@]} of ${#files[@]} files: ${bad[*]:0:8}"
    differ=1
  fi
}

# run_both NAME SITE [RUN OPTIONS]: `occmap run` of each binary, then compare.
run_both() {
  local name=$1 site=$2 bin tag
  shift 2
  for tag in old new; do
    bin=$old
    [ $tag = new ] && bin=$new
    (cd "$repo" && "$bin" run "$site" --out "$work/$name-$tag" --no-video --no-cache --no-wall-clock "$@") \
      >"$work/$name-$tag.log" 2>&1 || { echo "$name: $tag run failed: $(tail -2 "$work/$name-$tag.log")"; differ=1; return; }
  done
  compare "$name" "$work/$name-old" "$work/$name-new"
}

render() {  # render DIR SYNTH_OPTIONS...: by NEW, from the repository (its relative dataset paths)
  local dir=$1
  shift
  [ -f "$dir/site.yaml" ] && return 0
  (cd "$repo" && "$new" synth --out "$dir" "$@") >"$dir.synth.log" 2>&1 ||
    { echo "render $*: $(tail -2 "$dir.synth.log")"; return 1; }
}

for s in "${scenes[@]}"; do
  case $s in
    lab)
      render "$work/lab" --scene lab --frames 60 && run_both lab "$work/lab/site.yaml" || differ=1 ;;
    plaza)
      render "$work/plaza" --scene plaza --scale 0.25 --frames 120 && run_both plaza "$work/plaza/site.yaml" || differ=1 ;;
    wildtrack)
      if [ ! -d "$datasets/wildtrack/calibrations" ]; then
        echo "wildtrack: skipped (no $datasets/wildtrack)"
      else
        render "$work/wildtrack" --scene wildtrack --scale 0.25 --frames 20 && run_both wildtrack "$work/wildtrack/site.yaml" || differ=1
      fi ;;
    gopro4)
      if [ ! -d "$datasets/gopro4" ]; then echo "gopro4: skipped (no $datasets/gopro4)"; else run_both gopro4 sites/gopro4.yaml; fi ;;
    edge)
      if ! command -v mosquitto >/dev/null && [ ! -x /usr/sbin/mosquitto ]; then
        echo "edge: skipped (no mosquitto)"
        continue
      fi
      render "$work/lab" --scene lab --frames 60 || { differ=1; continue; }
      tl_broker
      for tag in old new; do
        bin=$old
        [ $tag = new ] && bin=$new
        "$bin" fuse "$work/lab/site.yaml" --broker "mqtt://127.0.0.1:$broker_port" --out "$work/edge-$tag" --no-video \
          --no-wall-clock --latency-budget-s 60 --dead-after-s 60 --threads 1 >"$work/edge-$tag.log" 2>&1 &
        fuse_pid=$!
        tl_track $fuse_pid
        tl_wait_for "$work/edge-$tag.log" "subscribed to" 20
        edge_pids=()
        for cams in cam1,cam2 cam3,cam4; do
          "$bin" edge "$work/lab/site.yaml" --cameras $cams --broker "mqtt://127.0.0.1:$broker_port" --threads 1 \
            >>"$work/edge-$tag-edges.log" 2>&1 &
          edge_pids+=($!)
          tl_track $!
        done
        for p in "${edge_pids[@]}"; do wait "$p" || echo "edge: an edge of $tag exited $?"; done
        for _ in $(seq 1200); do kill -0 $fuse_pid 2>/dev/null || break; sleep 0.05; done
        wait $fuse_pid || { echo "edge: the $tag fuse failed: $(tail -2 "$work/edge-$tag.log")"; differ=1; }
      done
      compare edge "$work/edge-old" "$work/edge-new" ;;
  esac
done
exit $differ
