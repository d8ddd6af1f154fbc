#!/usr/bin/env bash
# Times LaMa against the reference code in the same run on this machine: a big-lama-sized generator
# (ngf 64, 18 residual blocks: big-lama's layout and size) with seeded random weights, the reference
# code's inference (bin/predict.py's steps under PyPI's torch) and `instainpaint inpaint` on the very
# same file, photo and region. The photo is the statue's, padded to 512 x 512, and both paint the whole
# of it (`inpaint --whole-photo`, as bin/predict.py does). Prints seconds (min / median / max of the
# repeats) and the peak memory of each.
#
#   scripts/measure-inpainter.sh LAMA [--threads N] [--repeat R]
# LAMA: a git mirror or work tree of github.com/advimman/lama. Example:
#   scripts/measure-inpainter.sh /work/.mirror/advimman+lama/repo --repeat 3
set -euo pipefail
if [ $# -lt 1 ] || [ "$1" = -h ] || [ "$1" = --help ]; then sed -n '2,12p' "$0"; exit 0; fi
. "$(dirname "$0")/inpainter-reference/common.sh"
LAMA=$1; shift
THREADS=$(nproc); REPEAT=3
while [ $# -gt 0 ]; do
  case $1 in
    --threads) THREADS=$2; shift 2 ;; --repeat) REPEAT=$2; shift 2 ;;
    *) echo "error: unknown option $1" >&2; exit 1 ;;
  esac
done
BIN=${BIN:-$SEGMENTER_REPO/build/instainpaint}
TMP=$(mktemp -d /tmp/measure-inpainter.XXXXXX)
trap 'rm -rf "$TMP"' EXIT
extract_lama "$LAMA" "$TMP/lama"
PYTHON=$(reference_python)
STATUE=${INSTAINPAINT_SHARED:-$SEGMENTER_REPO/../shared}/data/statue/images_2
# A 512 x 512 photo and its region: the statue's photo and label, padded (edge) to 512 square.
"$PYTHON" - "$STATUE/IMG_2707.png" "$STATUE/label/IMG_2707.png" "$TMP" <<'PY'
import sys
import numpy as np
from PIL import Image
photo, label = (np.array(Image.open(p).convert(m)) for p, m in ((sys.argv[1], "RGB"), (sys.argv[2], "L")))
h, w = label.shape
pad = ((0, 512 - h), (0, 512 - w))
Image.fromarray(np.pad(photo, pad + ((0, 0),), mode="edge")).save(f"{sys.argv[3]}/photo.png")
Image.fromarray(np.pad(label, pad)).save(f"{sys.argv[3]}/mask.png")
PY
echo "machine: $(lscpu | sed -n 's/^Model name: *//p'), $THREADS threads; $(git -C "$SEGMENTER_REPO" rev-parse --short HEAD); $(date -u +%F)"
"$PYTHON" "$INPAINTER_REFERENCE_DIR/bench_reference.py" --lama "$TMP/lama" --image "$TMP/photo.png" \
  --mask "$TMP/mask.png" --save "$TMP/best.ckpt" --threads "$THREADS" --repeat "$REPEAT" > "$TMP/ref.json"
python3 - "$TMP/ref.json" <<'PY'
import json, statistics, sys
ref = json.load(open(sys.argv[1]))
def mmm(v): return f"{min(v):.3f} / {statistics.median(v):.3f} / {max(v):.3f}"
print(f"reference (torch {ref['torch']}): {mmm(ref['seconds'])} s, peak {ref['peak_mb']:.0f} MB")
PY
# The default precision (bf16 where the CPU has it), then float, the reference's arithmetic.
for precision in auto fp32; do
  /usr/bin/time -f "%M" -o "$TMP/native.rss" "$BIN" inpaint --inpainter "$TMP/best.ckpt" --image "$TMP/photo.png" \
    --mask "$TMP/mask.png" --out "$TMP/native.png" --threads "$THREADS" --repeat "$REPEAT" --whole-photo \
    --precision "$precision" --json > "$TMP/native.json"
  python3 - "$TMP/native.json" "$TMP/native.rss" <<'PY'
import json, sys
native = json.load(open(sys.argv[1]))
rss = int(open(sys.argv[2]).read().split()[-1]) / 1024
st = {s["stage"]: s for s in native["stages"]}
paint = st["paint"]
print(f"native {native['inpainter']['precision']} ({native['inpainter']['network']}): "
      f"{paint['ms'] / paint['calls'] / 1000:.3f} s (mean of {paint['calls']}, the first included); "
      f"read the file {st['read inpainter']['ms'] / 1000:.3f} s; peak {rss:.0f} MB")
PY
done
