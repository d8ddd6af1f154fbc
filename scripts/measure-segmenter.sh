#!/usr/bin/env bash
# Times the segmenter against the reference code in the same run on this machine: for each
# layout, the reference SamPredictor under PyPI's torch (scripts/segmenter-reference/, seeded
# random weights saved as the authors save theirs) and `instainpaint segment` on the very same
# file, photo and click. Prints the encoder's (set_image) and one click's (predict) seconds:
# min / median / max over the repeats, and the native command's whole time.
#
#   scripts/measure-segmenter.sh SAM MOBILE_SAM [--layouts "vit_t vit_b"] [--image PHOTO]
#       [--click X,Y] [--threads N] [--repeat R]
# SAM and MOBILE_SAM: git mirrors or work trees of github.com/facebookresearch/segment-anything
# and github.com/ChaoningZhang/MobileSAM. Example:
#   scripts/measure-segmenter.sh /work/.mirror/facebookresearch+segment-anything/repo \
#       /work/.mirror/ChaoningZhang+MobileSAM/repo --layouts "vit_t vit_b"
set -euo pipefail
if [ $# -lt 2 ] || [ "$1" = -h ] || [ "$1" = --help ]; then sed -n '2,13p' "$0"; exit 0; fi
. "$(dirname "$0")/segmenter-reference/common.sh"
SAM=$1; MOBILE=$2; shift 2
LAYOUTS="vit_t"; IMAGE=$SEGMENTER_REPO/../shared/data/statue/images_2/IMG_2707.png; CLICK=301,259
THREADS=$(nproc); REPEAT=3
while [ $# -gt 0 ]; do
  case $1 in
    --layouts) LAYOUTS=$2; shift 2 ;; --image) IMAGE=$2; shift 2 ;; --click) CLICK=$2; shift 2 ;;
    --threads) THREADS=$2; shift 2 ;; --repeat) REPEAT=$2; shift 2 ;;
    *) echo "error: unknown option $1" >&2; exit 1 ;;
  esac
done
BIN=${BIN:-$SEGMENTER_REPO/build/instainpaint}
TMP=$(mktemp -d /tmp/measure-segmenter.XXXXXX)
trap 'rm -rf "$TMP"' EXIT
extract_reference_packages "$SAM" "$MOBILE" "$TMP"
PYTHON=$(reference_python)
echo "machine: $(lscpu | sed -n 's/^Model name: *//p'), $THREADS threads; $(git -C "$SEGMENTER_REPO" rev-parse --short HEAD); $(date -u +%F)"
for layout in $LAYOUTS; do
  package=$TMP/sam; [ "$layout" = vit_t ] && package=$TMP/mobile
  "$PYTHON" "$SEGMENTER_REFERENCE_DIR/bench_reference.py" --package "$package" --layout "$layout" --image "$IMAGE" \
    --click "$CLICK" --save "$TMP/$layout.pt" --threads "$THREADS" --repeat "$REPEAT" > "$TMP/ref.json" 2>"$TMP/ref.err" ||
    { cat "$TMP/ref.err" >&2; exit 1; }
  python3 - "$layout" "$TMP/ref.json" <<'PY'
import json, statistics, sys
ref = json.load(open(sys.argv[2]))
def mmm(v): return f"{min(v):.3f} / {statistics.median(v):.3f} / {max(v):.3f}"
print(f"{sys.argv[1]}: reference (torch {ref['torch']}) encode {mmm(ref['encode_s'])} s, click {mmm(ref['decode_s'])} s")
PY
  # The default precision (bf16 where the CPU has it), then float, the reference's arithmetic.
  for precision in auto fp32; do
    start=$(date +%s.%N)
    "$BIN" segment --segmenter "$TMP/$layout.pt" --image "$IMAGE" --click "$CLICK" --out "$TMP/mask.png" \
      --threads "$THREADS" --repeat "$REPEAT" --precision "$precision" --json > "$TMP/native.json"
    whole=$(echo "$(date +%s.%N) - $start" | bc)
    python3 - "$layout" "$TMP/native.json" "$whole" <<'PY'
import json, sys
native, whole = json.load(open(sys.argv[2])), float(sys.argv[3])
st = {s["stage"]: s for s in native["stages"]}
enc = st["encode photo"]; dec = st["decode prompt"]
print(f"{sys.argv[1]}: native {native['precision']} encode {enc['ms'] / enc['calls'] / 1000:.3f} s (mean of {enc['calls']}), "
      f"click {dec['ms'] / dec['calls'] / 1000:.3f} s; read model {st['read segmenter']['ms'] / 1000:.3f} s; "
      f"whole command {whole:.2f} s")
PY
  done
done
