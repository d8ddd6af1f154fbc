#!/usr/bin/env bash
# Measures --refine (issue 21) with the default model (or --checkpoint):
#   rooms:  the model card's evaluation rooms (synth --seed 9000, never used in training), at
#           128² (8 rooms) and 256² (4 rooms), 12 input views and 4 object-free test views each:
#           PSNR, SSIM, masked PSNR, masked SSIM of the test views for --refine 0, 100, 300, with
#           the rooms' own context views and exact object-free reference (a perfect 2D inpainter);
#   statue: ../shared/data/statue with every 8th view held out (it shows the statue, so only
#           the pixels outside its mask are compared), at 256 rows, --refine 0 vs 300.
# Each run's time per step and peak memory (RSS) go beside its metrics in results.tsv.
#
#   scripts/measure-refinement.sh [--bin build/instainpaint] [--out refinement] [--checkpoint FILE]
#       [--steps "0 100 300"] [--rooms128 8] [--rooms256 4] [--shared ../shared]
set -euo pipefail
BIN=build/instainpaint OUT=refinement CHECKPOINT="" STEPS="0 100 300" ROOMS128=8 ROOMS256=4 SHARED=../shared
while [ $# -gt 0 ]; do
  case "$1" in
    --bin) BIN=$2; shift 2 ;;
    --out) OUT=$2; shift 2 ;;
    --checkpoint) CHECKPOINT=$2; shift 2 ;;
    --steps) STEPS=$2; shift 2 ;;
    --rooms128) ROOMS128=$2; shift 2 ;;
    --rooms256) ROOMS256=$2; shift 2 ;;
    --shared) SHARED=$2; shift 2 ;;
    -h|--help) sed -n '2,12p' "$0"; exit 0 ;;
    *) echo "unknown argument $1" >&2; exit 2 ;;
  esac
done
MODEL=()
[ -n "$CHECKPOINT" ] && MODEL=(--checkpoint "$CHECKPOINT")
mkdir -p "$OUT"
printf 'set\tscene\tsteps\tpsnr\tssim\tmasked_psnr\tmasked_ssim\toutside_psnr\toutside_ssim\tms_per_step\trefine_s\tpeak_rss_mb\n' \
  > "$OUT/results.tsv"

# evaluate <set> <scene dir> <steps> <eval args...>: one eval, one row of results.tsv.
evaluate() {
  local set=$1 scene=$2 steps=$3
  shift 3
  local dir="$OUT/$set-$(basename "$scene")-$steps"
  /usr/bin/time -f '%M' -o "$dir.rss" "$BIN" eval --scene "$scene" --out "$dir" --refine "$steps" --no-report \
    "${MODEL[@]}" "$@" > "$dir.log" 2>&1 || { echo "failed: see $dir.log" >&2; exit 1; }
  python3 - "$dir/metrics.json" "$dir.rss" "$set" "$(basename "$scene")" "$steps" >> "$OUT/results.tsv" <<'PY'
import json, sys
m = json.load(open(sys.argv[1]))
rss_mb = int(open(sys.argv[2]).read().split()[-1]) / 1024
refine = m["prediction"].get("after_prediction", {}).get("refine", {})
cell = lambda v, d: "" if v is None else (v if isinstance(v, str) else f"{v:.{d}f}")
row = sys.argv[3:6]
for key, d in [("psnr", 2), ("ssim", 3), ("masked_psnr", 2), ("masked_ssim", 3), ("outside_psnr", 2), ("outside_ssim", 3)]:
    row.append(cell(m["mean"].get(key), d))
ms = refine.get("ms_per_step")
row += [cell(ms, 0), cell(ms * refine["steps"] / 1000 if ms else None, 1), f"{rss_mb:.0f}"]
print("\t".join(row))
PY
  echo "$(tail -1 "$OUT/results.tsv")"
}

for size in 128 256; do
  rooms=$ROOMS128
  [ "$size" = 256 ] && rooms=$ROOMS256
  [ "$rooms" -gt 0 ] || continue
  "$BIN" synth --out "$OUT/rooms-$size" --scenes "$rooms" --seed 9000 --views 12 --test-views 4 \
    --width "$size" --height "$size" --degrade none > "$OUT/synth-$size.log" 2>&1
  for room in "$OUT/rooms-$size"/scene_*; do
    context=$(python3 -c "import json, sys; print(','.join(json.load(open(sys.argv[1]))['context']))" "$room/synth.json")
    for steps in $STEPS; do
      evaluate "rooms-$size" "$room" "$steps" --height "$size" --reference "$room/reference.png" --context "$context"
    done
  done
done

if [ -d "$SHARED/data/statue" ]; then
  for steps in 0 300; do evaluate statue "$SHARED/data/statue" "$steps" --height 256 --hold-out-every 8; done
fi

# Means per set and step count.
python3 - "$OUT/results.tsv" <<'PY'
import csv, collections, sys
rows = list(csv.DictReader(open(sys.argv[1]), delimiter="\t"))
groups = collections.OrderedDict()
for r in rows: groups.setdefault((r["set"], r["steps"]), []).append(r)
keys = ["psnr", "ssim", "masked_psnr", "masked_ssim", "outside_psnr", "outside_ssim", "ms_per_step", "refine_s", "peak_rss_mb"]
print("set\tsteps\tscenes\t" + "\t".join(keys))
for (s, n), rs in groups.items():
    cells = []
    for k in keys:
        v = [float(r[k]) for r in rs if r[k] not in ("", "inf")]
        cells.append(f"{sum(v) / len(v):.3f}" if v else "")
    print(f"{s}\t{n}\t{len(rs)}\t" + "\t".join(cells))
PY
