#!/usr/bin/env bash
# The plaza with the renderer's ideal camera and with a real one (`synth --real-camera`:
# automatic exposure and white balance following the content, sensor noise, supersampling,
# JPEG, contact shadows; see docs/formats.md), each run twice:
#   paper     the empty scene as each camera's background and |I - B| > T on luma (the paper's test)
#   adaptive  the plaza's own site: colour, backgrounds learned and kept from the fused map
# and scored by `occmap eval`. Prints per dataset and run: MODA, the share of pixels called
# changed, the share of pixels without an object called changed, change F1, and the share of
# shadow pixels called changed.
#
# Usage: scripts/real-camera-plaza.sh [OCCMAP_BINARY] [WORK_DIR]
#   env: SCALE (image scale, default 0.25), FRAMES (default 150), PEOPLE (default 16), SEED (1),
#        EXTRA (more synth flags for the real camera, e.g. "--overcast")
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
occmap=${1:-$here/build/release/apps/occmap}
work=${2:-$(mktemp -d /tmp/real-camera-plaza.XXXXXX)}
scale=${SCALE:-0.25}
frames=${FRAMES:-150}
people=${PEOPLE:-16}
seed=${SEED:-1}
mkdir -p "$work"

synth() {  # name, extra flags...
  local name=$1
  shift
  "$occmap" synth --scene plaza --scale "$scale" --frames "$frames" --people "$people" --seed "$seed" \
    --out "$work/$name" "$@" >/dev/null
  # The paper's site: the same cameras with the empty scene as background, the plain luma test.
  python3 - "$work/$name" <<'EOF'
import re, sys
folder = sys.argv[1]
text = open(f"{folder}/site.yaml").read()
text = re.sub(r"(\n    source: \{images: frames/([^/]+)/[^}]*\}\n)", r"\1    background: backgrounds/\2.png\n", text)
start = text.index("\ndetection:")
end = text.index("\n# A rendered person touches")
text = text[:start] + "\ndetection:\n  threshold: 20\n  tolerance_px: 1\n" + text[end:]
open(f"{folder}/site-paper.yaml", "w").write(text)
EOF
}

run() {  # dataset, site file, run name
  "$occmap" run "$work/$1/$2" --out "$work/$1-$3" --change-pngs --no-video >/dev/null
  "$occmap" eval "$work/$1" "$work/$1-$3" --json >"$work/$1-$3.json"
}

synth ideal --ideal-camera
synth real --real-camera ${EXTRA:-}
for d in ideal real; do
  run "$d" site-paper.yaml paper
  run "$d" site.yaml adaptive
done

python3 - "$work" <<'EOF'
import json, sys
work = sys.argv[1]
print(f"{'camera':6} {'test':9} {'MODA':>6} {'changed':>8} {'false':>7} {'F1':>6} {'shadow':>7}")
for d in ("ideal", "real"):
    for r in ("paper", "adaptive"):
        j = json.load(open(f"{work}/{d}-{r}.json"))
        c = j["changes"]
        total = c["tp"] + c["fp"] + c["fn"] + c["tn"]
        changed = (c["tp"] + c["fp"]) / total
        false = c["fp"] / max(1, c["fp"] + c["tn"])
        shadow = c["shadow_changed_fraction"]
        f1 = c["f1"]
        print(f"{d:6} {r:9} {j['detection']['moda']:6.3f} {changed:8.1%} {false:7.1%} "
              f"{(f1 if f1 is not None else float('nan')):6.3f} "
              f"{(shadow if shadow is not None else float('nan')):7.1%}")
print(f"(work folder: {work})")
EOF
