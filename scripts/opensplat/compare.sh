#!/usr/bin/env bash
# `instainpaint reconstruct` against OpenSplat on the same capture: the same training views at the
# same size, the same start points (reconstruct --write-colmap writes them as a COLMAP folder,
# which OpenSplat reads), the same number of steps, OpenSplat's schedule scaled to that length as
# ours is; both trainers' splats scored by the same renderer on the held-out views (every 8th).
# One after the other on this machine, each timed as a whole process (wall, peak memory).
#
#   scripts/opensplat/compare.sh OPENSPLAT SCENE OUT [STEPS] [HEIGHT]
#     OPENSPLAT  the executable (scripts/opensplat/build.sh makes it)
#     STEPS      default 3000; HEIGHT default 256 rows
# Writes OUT/summary.json and prints one line per trainer.
set -euo pipefail
if [[ $# -lt 3 || $1 == -h || $1 == --help ]]; then sed -n 2,11p "$0"; exit 2; fi
opensplat=$(realpath "$1"); scene=$(realpath "$2"); out=$(realpath -m "$3")
steps=${4:-3000}; height=${5:-256}
here=$(cd "$(dirname "$0")/../.." && pwd)
ii=${INSTAINPAINT:-$here/build/instainpaint}
mkdir -p "$out"
timed() {  # log-file command...: the command's wall seconds and peak RSS (kB) into log-file.time
  local log=$1; shift
  /usr/bin/time -f '%e %M' -o "$log.time" "$@" >"$log" 2>&1 || { tail -20 "$log"; exit 1; }
}

# Ours: trains, scores its held-out views, and writes the start it used for OpenSplat.
timed "$out/ours.log" "$ii" reconstruct "$scene" --height "$height" --eval --steps "$steps" \
  --checkpoint-every 0 --out "$out/ours.ply" --write-colmap "$out/colmap"

# OpenSplat on that folder: 3DGS's schedule of 30,000 steps scaled to STEPS (downscales, SH
# degrees, warm-up, opacity resets every tenth; it stops splitting at half the run itself).
timed "$out/opensplat.log" "$opensplat" "$out/colmap" -o "$out/opensplat.ply" -n "$steps" --keep-crs --cpu \
  --num-downscales 2 --resolution-schedule $((steps / 10)) --sh-degree-interval $((steps / 10)) \
  --warmup-length $((steps / 60)) --refine-every 100 --reset-alpha-every $(((steps / 10 + 99) / 100)) \
  --stop-screen-size-at $((steps * 4000 / 30000))

# OpenSplat's splats scored as ours were (its PLY in the capture's frame: --keep-crs), in front of
# the colour it trained them in front of (nerfstudio's default, model.hpp), ours in front of white.
"$ii" reconstruct "$scene" --height "$height" --eval --steps 0 --start "$out/opensplat.ply" \
  --background 0.6130,0.0101,0.3984 --out "$out/opensplat-scored.ply" >"$out/opensplat-scored.log" 2>&1

python3 - "$out" "$steps" "$height" "$scene" <<'PY'
import json, sys
out, steps, height, scene = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
def timing(name):
    wall, rss = open(f"{out}/{name}.log.time").read().split()[-2:]
    return float(wall), int(rss) / 1024
ours = json.load(open(f"{out}/ours.json")); theirs = json.load(open(f"{out}/opensplat-scored.json"))
rows = {}
for name, report in (("instainpaint", ours), ("opensplat", theirs)):
    wall, rss = timing("ours" if name == "instainpaint" else "opensplat")
    rows[name] = {"psnr": report["psnr"], "ssim": report["ssim"], "splats": report["splats"],
                  "wall_s": wall, "peak_rss_mb": rss}
    print(f"{name:13s} held-out PSNR {report['psnr']:.2f} dB  SSIM {report['ssim']:.4f}  "
          f"{report['splats']} splats  {wall:.0f} s  {rss:.0f} MB")
json.dump({"scene": scene, "steps": steps, "height": height, "held_out": ours["held_out"],
           "start_points": ours["start"], **rows}, open(f"{out}/summary.json", "w"), indent=2)
PY
