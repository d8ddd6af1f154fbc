#!/usr/bin/env bash
# Measures --refine with the default model (or --checkpoint):
#   rooms:  the model card's evaluation rooms (synth --seed 9000, never used in training), at
#           128² (8 rooms) and 256² (4 rooms), 12 input views and 4 object-free test views each:
#           PSNR, SSIM, masked PSNR, masked SSIM of the test views for each of --rooms-settings,
#           with the rooms' own context views and exact object-free reference (a perfect 2D
#           inpainter);
#   statue: ../shared/data/statue with every 8th view held out (it shows the statue, so only
#           the pixels outside its mask are compared), at 256 rows, each of --settings;
#   fern:   ../shared/data/fern with every 8th view held out, a reconstruction (--keep-object:
#           compared whole), at 256 rows, each of --settings.
# Each run's steps, time and peak memory (RSS) go beside its metrics in results.tsv; each
# refined run's loss curve is OUT/<set>-<scene>-<setting>/refine-loss.png.
#
#   scripts/measure-refinement.sh [--bin build/instainpaint] [--out refinement] [--checkpoint FILE]
#       [--rooms-settings "0 fast"] [--settings "0 fast best"] [--rooms128 8] [--rooms256 4]
#       [--shared ../shared]
set -euo pipefail
BIN=build/instainpaint OUT=refinement CHECKPOINT="" ROOM_SETTINGS="0 fast" SETTINGS="0 fast best" ROOMS128=8 ROOMS256=4
SHARED=../shared
while [ $# -gt 0 ]; do
  case "$1" in
    --bin) BIN=$2; shift 2 ;;
    --out) OUT=$2; shift 2 ;;
    --checkpoint) CHECKPOINT=$2; shift 2 ;;
    --rooms-settings) ROOM_SETTINGS=$2; shift 2 ;;
    --settings) SETTINGS=$2; shift 2 ;;
    --rooms128) ROOMS128=$2; shift 2 ;;
    --rooms256) ROOMS256=$2; shift 2 ;;
    --shared) SHARED=$2; shift 2 ;;
    -h|--help) sed -n '2,19p' "$0"; exit 0 ;;
    *) echo "unknown argument $1" >&2; exit 2 ;;
  esac
done
MODEL=()
[ -n "$CHECKPOINT" ] && MODEL=(--checkpoint "$CHECKPOINT")
mkdir -p "$OUT"
printf 'set\tscene\tsetting\tpsnr\tssim\tmasked_psnr\tmasked_ssim\toutside_psnr\toutside_ssim\tsteps\tms_per_step\trefine_s\tpeak_rss_mb\n' \
  > "$OUT/results.tsv"

# evaluate <set> <scene dir> <setting> <eval args...>: one eval, one row of results.tsv.
evaluate() {
  local set=$1 scene=$2 setting=$3
  shift 3
  local dir="$OUT/$set-$(basename "$scene")-$setting"
  /usr/bin/time -f '%M' -o "$dir.rss" "$BIN" eval --scene "$scene" --out "$dir" --refine "$setting" --no-report \
    "${MODEL[@]}" "$@" > "$dir.log" 2>&1 || { echo "failed: see $dir.log" >&2; exit 1; }
  python3 - "$dir/metrics.json" "$dir.rss" "$set" "$(basename "$scene")" "$setting" >> "$OUT/results.tsv" <<'PY'
import json, sys
m = json.load(open(sys.argv[1]))
rss_mb = int(open(sys.argv[2]).read().split()[-1]) / 1024
refine = m["prediction"].get("after_prediction", {}).get("refine", {})
cell = lambda v, d: "" if v is None else (v if isinstance(v, str) else f"{v:.{d}f}")
row = sys.argv[3:6]
for key, d in [("psnr", 2), ("ssim", 3), ("masked_psnr", 2), ("masked_ssim", 3), ("outside_psnr", 2), ("outside_ssim", 3)]:
    row.append(cell(m["mean"].get(key), d))
row += [str(refine.get("steps", 0)), cell(refine.get("ms_per_step"), 0), cell(refine.get("seconds"), 1), f"{rss_mb:.0f}"]
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
    for setting in $ROOM_SETTINGS; do
      evaluate "rooms-$size" "$room" "$setting" --height "$size" --reference "$room/reference.png" --context "$context"
    done
  done
done

for setting in $SETTINGS; do
  [ -d "$SHARED/data/statue" ] && evaluate statue "$SHARED/data/statue" "$setting" --height 256 --hold-out-every 8
  [ -d "$SHARED/data/fern" ] && evaluate fern "$SHARED/data/fern" "$setting" --height 256 --hold-out-every 8 --keep-object
done

# Means per set and step count.
python3 - "$OUT/results.tsv" <<'PY'
import csv, collections, sys
rows = list(csv.DictReader(open(sys.argv[1]), delimiter="\t"))
groups = collections.OrderedDict()
for r in rows: groups.setdefault((r["set"], r["setting"]), []).append(r)
keys = ["psnr", "ssim", "masked_psnr", "masked_ssim", "outside_psnr", "outside_ssim", "steps", "ms_per_step", "refine_s", "peak_rss_mb"]
print("set\tsetting\tscenes\t" + "\t".join(keys))
for (s, n), rs in groups.items():
    cells = []
    for k in keys:
        v = [float(r[k]) for r in rs if r[k] not in ("", "inf")]
        cells.append(f"{sum(v) / len(v):.3f}" if v else "")
    print(f"{s}\t{n}\t{len(rs)}\t" + "\t".join(cells))
PY
