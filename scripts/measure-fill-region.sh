#!/usr/bin/env bash
# The filled region on a real capture with object-free photos (SPIn-NeRF layout):
#  1. the capture refined into splats with its object kept (infer --keep-object --refine 3m);
#  2. ground-truth reference: for each test view given, the object removed with that view's test
#     mask as the stroke and filled with its own photo as the reference (fill --view --mask
#     --reference), scored on the other test views (eval --gaussians --reference-view): the
#     region beside the whole image, and the region's uncovered pixels;
#  3. learned reference: the object removed with the reference view's label mask as the stroke,
#     filled with a 2D inpainter's picture of it, scored on every test view.
# Each placement of --placements is measured. OUT/results.tsv holds the table; OUT/<run>/ each
# run's fill report and metrics.json; OUT/<placement>-regions.png crops of three test views
# (truth, then each placement).
#
#   scripts/measure-fill-region.sh --scene DIR [--images images_4] [--bin build/instainpaint]
#       [--out fill-region] [--truth-views A,B,C] [--learned VIEW:PICTURE] [--placements "surface network"]
set -euo pipefail
BIN=build/instainpaint OUT=fill-region SCENE="" IMAGES=images_4 TRUTH="" LEARNED="" PLACEMENTS="surface network"
while [ $# -gt 0 ]; do
  case "$1" in
    --bin) BIN=$2; shift 2 ;;
    --out) OUT=$2; shift 2 ;;
    --scene) SCENE=$2; shift 2 ;;
    --images) IMAGES=$2; shift 2 ;;
    --truth-views) TRUTH=$2; shift 2 ;;
    --learned) LEARNED=$2; shift 2 ;;
    --placements) PLACEMENTS=$2; shift 2 ;;
    -h|--help) sed -n '2,16p' "$0"; exit 0 ;;
    *) echo "unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
done
[ -n "$SCENE" ] || { echo "--scene DIR is required (see --help)" >&2; exit 2; }
mkdir -p "$OUT"
say() { echo "measure-fill-region: $*" >&2; }
scene_args=(--scene "$SCENE" --images "$IMAGES")

if [ ! -f "$OUT/splats/gaussians.ply" ]; then
  say "the capture refined into splats, object kept (3 minutes)"
  "$BIN" infer "${scene_args[@]}" --keep-object --refine 3m --out "$OUT/splats" > "$OUT/infer.log" 2>&1
fi

# The mask file of a view: test_label/ pairs its files with the test views in name order.
mask_of() {  # view kind(test|label)
  python3 - "$SCENE/$IMAGES" "$1" "$2" <<'EOF'
import os, sys
folder, view, kind = sys.argv[1:4]
images = sorted(f for f in os.listdir(folder) if os.path.isfile(os.path.join(folder, f)))
stems = [os.path.splitext(f)[0] for f in images]
if kind == "label":
    print(os.path.join(folder, "label", view + ".png")); sys.exit()
labels = sorted(os.listdir(os.path.join(folder, "test_label")))
print(os.path.join(folder, "test_label", labels[stems.index(view)]))
EOF
}

printf 'reference\tplacement\tview\twhole_psnr\tregion_psnr\tregion_minus_whole\tregion_ssim\tuncovered_pixels\tviews_uncovered\tfill_seconds\n' > "$OUT/results.tsv"
record() {  # kind placement view run
  python3 - "$OUT/$4" "$1" "$2" "$3" >> "$OUT/results.tsv" <<'EOF'
import json, sys
run, kind, placement, view = sys.argv[1:5]
m = json.load(open(run + "/metrics.json"))
f = json.load(open(run + "/fill/fill.json"))
rw = m["region_and_whole"]
print("\t".join([kind, placement, view, "%.2f" % rw["psnr"]["whole"], "%.2f" % rw["psnr"]["region"],
                 "%+.2f" % rw["psnr"]["region_minus_whole"], "%.4f" % rw["ssim"]["region"],
                 str(rw["uncovered"]["pixels"]), str(rw["uncovered"]["views"]), "%.2f" % (f["total_ms"] / 1000)]))
EOF
  tail -1 "$OUT/results.tsv" >&2
}

fill_and_score() {  # kind placement view mask reference eval-args...
  local kind=$1 placement=$2 view=$3 mask=$4 reference=$5
  shift 5
  local run="$kind-$placement-$view"
  mkdir -p "$OUT/$run"
  "$BIN" fill "$OUT/splats/gaussians.ply" "${scene_args[@]}" --view "$view" --mask "$mask" --reference "$reference" \
    --placement "$placement" --out "$OUT/$run/filled.ply" --report "$OUT/$run/fill" > "$OUT/$run/fill.log" 2>&1
  "$BIN" eval "${scene_args[@]}" --gaussians "$OUT/$run/filled.ply" "$@" --out "$OUT/$run" > "$OUT/$run/eval.log" 2>&1
  record "$kind" "$placement" "$view" "$run"
}

for placement in $PLACEMENTS; do
  for view in ${TRUTH//,/ }; do
    fill_and_score truth "$placement" "$view" "$(mask_of "$view" test)" "$SCENE/$IMAGES/$view.png" --reference-view "$view"
  done
  if [ -n "$LEARNED" ]; then
    IFS=: read -r view picture <<< "$LEARNED"
    fill_and_score learned "$placement" "$view" "$(mask_of "$view" label)" "$picture"
  fi
done

# Means of the ground-truth rows per placement.
python3 - "$OUT/results.tsv" <<'EOF' | tee "$OUT/means.tsv" >&2
import csv, sys
rows = [r for r in csv.DictReader(open(sys.argv[1]), delimiter="\t") if r["reference"] == "truth"]
for p in sorted({r["placement"] for r in rows}):
    rs = [r for r in rows if r["placement"] == p]
    mean = lambda k: sum(float(r[k]) for r in rs) / len(rs)
    print("truth mean\t%s\t%d views\twhole %.2f\tregion %.2f\t%+.2f dB\tuncovered %d" % (
        p, len(rs), mean("whole_psnr"), mean("region_psnr"), mean("region_minus_whole"),
        sum(int(r["uncovered_pixels"]) for r in rs)))
EOF

# Crops around the region of three scored test views of the first truth view's runs: the truth,
# then each placement.
first=${TRUTH%%,*}
if [ -n "$first" ]; then
  runs=()
  for placement in $PLACEMENTS; do runs+=("$OUT/truth-$placement-$first"); done
  mapfile -t views < <(ls "${runs[0]}/renders" | awk '{a[NR]=$0} END{print a[1]; print a[int((NR+1)/2)]; print a[NR]}')
  inputs=() filter="" row=0
  for v in "${views[@]}"; do
    inputs+=(-i "${runs[0]}/sheets/$v")
    filter+="[$((row * (${#runs[@]} + 1)))]crop=iw/4:ih:0:0[t$row];"
    col=1
    for run in "${runs[@]}"; do
      inputs+=(-i "$run/sheets/$v")
      filter+="[$((row * (${#runs[@]} + 1) + col))]crop=iw/4:ih:3*iw/4:0[c${row}_$col];"
      col=$((col + 1))
    done
    filter+="[t$row]$(for c in $(seq 1 ${#runs[@]}); do printf '[c%s_%s]' $row $c; done)hstack=$((${#runs[@]} + 1))[r$row];"
    row=$((row + 1))
  done
  ffmpeg -loglevel error -y "${inputs[@]}" -filter_complex "${filter}[r0][r1][r2]vstack=3" "$OUT/regions.png"
  say "wrote $OUT/regions.png (rows: three test views; columns: truth, $PLACEMENTS; the region outlined)"
fi
say "wrote $OUT/results.tsv and $OUT/means.tsv"
