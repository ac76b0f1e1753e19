#!/usr/bin/env bash
# Generality probes of the station beyond the synthetic renderer's own look: posed
# subjects, bodies outside the shape library, a white / black / grey studio backdrop,
# other resolutions, JPEG frames, MP4s as ffmpeg writes them (High profile, B-frames;
# needs ffmpeg), and cast shadows coloured as under a warm key and a cool ambient light.
# Needs python3 with opencv-python-headless and numpy. Usage: bash tools/probes.sh [DIR]
set -euo pipefail
dir=${1:-/tmp/fitstation-probes}
bin=${FITSTATION:-target/release/fitstation}
mkdir -p "$dir"
summary() {
  python3 -c '
import json, sys
t = json.load(open(sys.argv[1] + "/truth.json"))["measurements_mm"]
r = json.load(open(sys.argv[2] + "/report.json"))
m = r["measurements_mm"]
keys = ["chest_girth", "waist_girth", "hip_girth", "thigh_girth_left", "thigh_girth_right", "stature"]
print("%-10s fitted %2d/%2d  " % (sys.argv[3], r["frames"]["fitted"], r["frames"]["with_subject"])
      + "  ".join("%s %+6.1f" % (k.split("_")[0] + ("_" + k.split("_")[-1][0] if "thigh" in k else ""), m[k] - t[k]) for k in keys))
' "$1.truth" "$2" "$3"
}
for pose in "12 4" "-10 -3"; do
  set -- $pose
  out="$dir/pose_a$1_l$2"
  [ -d "$out" ] || "$bin" synth-set --out "$out" --count 12 --arms-deg "$1" --legs-deg "$2" > /dev/null
  echo "== arms $1 deg, legs $2 deg from the rest A-pose (fitstation eval)"
  "$bin" eval "$out"/subject_?? 2>&1 | sed -n '/^per measurement/,/^$/p'
done
# Bodies outside the shape library's span: a belly 10 % deeper about the waist; hips 6 %
# wider and 4 % flatter.
for warp in "0 0.10 0.6" "0.06 -0.04 0.52"; do
  set -- $warp
  out="$dir/warp_w$1_d$2_at$3"
  [ -d "$out" ] || "$bin" synth-set --out "$out" --count 12 --warp-width "$1" --warp-depth "$2" --warp-at "$3" > /dev/null
  echo "== trunk $1 wider, $2 deeper about $3 of the stature (fitstation eval)"
  "$bin" eval "$out"/subject_?? 2>&1 | sed -n '/^per measurement/,/^$/p'
done
base="$dir/base/subject_00"
[ -d "$base" ] || "$bin" synth-set --out "$dir/base" --count 1 --first-seed 1002 --format png > /dev/null
echo "== one subject (seed 1002), error of the replayed girths in mm"
"$bin" replay "$base" --out "$dir/out_base" > /dev/null 2>&1 || true
summary "$base" "$dir/out_base" original
for level in 255 0 128; do
  python3 tools/probe_backdrop.py "$base" "$dir/bd_$level" "$level"
  "$bin" replay "$dir/bd_$level" --out "$dir/out_bd_$level" > /dev/null 2>&1 || true
  summary "$base" "$dir/out_bd_$level" "backdrop$level"
done
for how in 0.5 1.5 jpeg:70 h264:1 h264:1.5; do
  name=$(echo "$how" | tr ':' '_')
  python3 tools/probe_rescale.py "$base" "$dir/rs_$name" "$how"
  "$bin" replay "$dir/rs_$name" --out "$dir/out_rs_$name" > /dev/null 2>&1 || true
  summary "$base" "$dir/out_rs_$name" "$how"
done
for strength in 1 2; do
  python3 tools/probe_shadow_tint.py "$base" "$dir/tint_$strength" "$strength"
  "$bin" replay "$dir/tint_$strength" --out "$dir/out_tint_$strength" > /dev/null 2>&1 || true
  summary "$base" "$dir/out_tint_$strength" "tint$strength"
done
