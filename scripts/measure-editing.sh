#!/usr/bin/env bash
# Measures insertion and multi-region removal on synthetic rooms with exact ground truth
# (`synth --task insert|multi`): masked PSNR on the test views of
#   insert: the model given true masks in every view, the model given one mask (the
#           reference's, propagated with --mode insert), the floor (nothing inserted) and the
#           sticker (the reference's region pasted flat at the background depth);
#   multi:  the model given true masks, and given one mask on the reference (its disjoint
#           regions lifted one by one).
#
#   scripts/measure-editing.sh [--bin build/instainpaint] [--rooms 4] [--seed 21] [--out editing]
#       [--checkpoint FILE]
set -euo pipefail
BIN=build/instainpaint ROOMS=4 SEED=21 OUT=editing CHECKPOINT=""
while [ $# -gt 0 ]; do
  case "$1" in
    --bin) BIN=$2; shift 2 ;;
    --rooms) ROOMS=$2; shift 2 ;;
    --seed) SEED=$2; shift 2 ;;
    --out) OUT=$2; shift 2 ;;
    --checkpoint) CHECKPOINT=$2; shift 2 ;;
    -h|--help) sed -n '2,12p' "$0"; exit 0 ;;
    *) echo "unknown argument $1" >&2; exit 2 ;;
  esac
done
MODEL=()
[ -n "$CHECKPOINT" ] && MODEL=(--checkpoint "$CHECKPOINT")
mkdir -p "$OUT"
: > "$OUT/results.tsv"

json_field() { python3 -c 'import json,sys; v=json.load(open(sys.argv[1]))[sys.argv[2]]; print(",".join(v) if isinstance(v, list) else v)' "$@"; }

# eval <task> <room> <label> <eval args...>: appends task, room, label, masked PSNR, regions.
evaluate() {
  local task=$1 room=$2 label=$3
  shift 3
  local dir="$OUT/$task-$(basename "$room")-$label"
  "$BIN" eval --scene "$room" --height 256 --out "$dir" "$@" > "$dir.log" 2>&1 ||
    { echo "failed: see $dir.log" >&2; exit 1; }
  python3 - "$dir/metrics.json" "$task" "$(basename "$room")" "$label" >> "$OUT/results.tsv" <<'PY'
import json, sys
m = json.load(open(sys.argv[1]))
regions = len(m["prediction"].get("edit", {}).get("regions", [])) or ""
print("\t".join(sys.argv[2:5] + ["%.2f" % m["mean"]["masked_psnr"], str(regions)]))
PY
}

for task in insert multi; do
  "$BIN" synth --out "$OUT/$task" --task "$task" --scenes "$ROOMS" --seed "$SEED" --views 12 --test-views 4 \
    --width 256 --height 256 --object procedural --degrade none > "$OUT/synth-$task.log" 2>&1
  for room in "$OUT/$task"/scene_*; do
    ref=$(json_field "$room/synth.json" reference)
    context=$(json_field "$room/synth.json" context)
    mode=remove
    [ "$task" = insert ] && mode=insert
    common=(--reference "$room/reference.png" --context "$context" "${MODEL[@]}")
    evaluate "$task" "$room" "model, true masks" "${common[@]}"
    evaluate "$task" "$room" "model, one mask" "${common[@]}" --view "$ref" --mask "$room/images_4/label/$ref.png" \
      --mode "$mode"
    if [ "$task" = insert ]; then
      evaluate "$task" "$room" floor --method floor
      evaluate "$task" "$room" sticker --method sticker --reference "$room/reference.png" --reference-view "$ref"
    fi
  done
done

python3 - "$OUT/results.tsv" <<'PY'
import collections, sys
rows = [l.rstrip("\n").split("\t") for l in open(sys.argv[1]) if l.strip()]
print("| task | room | method | masked PSNR | regions lifted |")
print("|---|---|---|---|---|")
for r in rows:
    print("| " + " | ".join(r) + " |")
means = collections.OrderedDict()
for task, room, label, psnr, _ in rows:
    means.setdefault((task, label), []).append(float(psnr))
for (task, label), values in means.items():
    print(f"| **{task}** | mean of {len(values)} | {label} | {sum(values) / len(values):.2f} | |")
PY
