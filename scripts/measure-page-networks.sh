#!/usr/bin/env bash
# The page with the learned networks at their real sizes, as a new user has it after
# `instainpaint models get mobile-sam big-lama`: MobileSAM full size and a big-lama-sized LaMa with
# seeded random weights (written by the reference code under PyPI's torch; the published files are
# not reachable from the machines that measure), checked into a models' cache of their own through a
# catalogue file pinning their MD5s, then `serve` with no network flag (auto):
#   - how long until every view's photo is encoded behind the page, then a click on 8 views;
#   - Run at 256 rows with the reference painted by Navier-Stokes (--inpainter ns) and by LaMa (auto),
#     after every view is encoded (a Run while a view is being encoded waits for it);
#   - the page's Fill of a million splats with a box, LaMa painting the hole (measure-serve-fill.py).
#
#   scripts/measure-page-networks.sh SAM MOBILE_SAM LAMA [--runs N] [--scene DIR] [--work DIR]
# SAM, MOBILE_SAM, LAMA: git mirrors or work trees of github.com/facebookresearch/segment-anything,
# github.com/ChaoningZhang/MobileSAM and github.com/advimman/lama. Example:
#   scripts/measure-page-networks.sh /work/.mirror/facebookresearch+segment-anything/repo \
#       /work/.mirror/ChaoningZhang+MobileSAM/repo /work/.mirror/advimman+lama/repo
set -euo pipefail
if [ $# -lt 3 ] || [ "$1" = -h ] || [ "$1" = --help ]; then sed -n '2,16p' "$0"; exit 0; fi
. "$(dirname "$0")/inpainter-reference/common.sh"
SAM=$1; MOBILE=$2; LAMA=$3; shift 3
RUNS=3; SCENE=$SEGMENTER_REPO/../shared/data/statue; WORK=""
while [ $# -gt 0 ]; do
  case $1 in
    --runs) RUNS=$2; shift 2 ;; --scene) SCENE=$2; shift 2 ;; --work) WORK=$2; shift 2 ;;
    *) echo "error: unknown option $1" >&2; exit 1 ;;
  esac
done
BIN=${BIN:-$SEGMENTER_REPO/build/instainpaint}
TMP=$(mktemp -d /tmp/measure-page-networks.XXXXXX)
trap 'rm -rf "$TMP"' EXIT
WORK=${WORK:-$TMP/work}
mkdir -p "$WORK"
PYTHON=$(reference_python)
PHOTO=$SEGMENTER_REPO/../shared/data/statue/images_2/IMG_2707.png
LABEL=$SEGMENTER_REPO/../shared/data/statue/images_2/label/IMG_2707.png
if [ ! -f "$WORK/mobile_sam.pt" ]; then
  extract_reference_packages "$SAM" "$MOBILE" "$TMP/ref"
  "$PYTHON" "$SEGMENTER_REFERENCE_DIR/bench_reference.py" --package "$TMP/ref/mobile" --layout vit_t \
    --image "$PHOTO" --click 301,259 --save "$WORK/mobile_sam.pt" --repeat 1 > /dev/null
fi
if [ ! -f "$WORK/big-lama.ckpt" ]; then
  extract_lama "$LAMA" "$TMP/lama"
  "$PYTHON" "$INPAINTER_REFERENCE_DIR/bench_reference.py" --lama "$TMP/lama" --image "$PHOTO" --mask "$LABEL" \
    --save "$WORK/big-lama.ckpt" --repeat 1 > /dev/null
fi
# The seeded files pinned by their own MD5s, under the catalogue's names.
cat > "$WORK/catalogue.json" <<JSON
[{"name": "mobile-sam", "role": "segmenter", "file": "mobile_sam.pt", "urls": ["http://127.0.0.1:9/mobile_sam.pt"],
  "md5": "$(md5sum "$WORK/mobile_sam.pt" | cut -c1-32)", "checksum_source": "the seeded file"},
 {"name": "big-lama", "role": "inpainter", "file": "big-lama.pt", "urls": ["http://127.0.0.1:9/big-lama.pt"],
  "md5": "$(md5sum "$WORK/big-lama.ckpt" | cut -c1-32)", "checksum_source": "the seeded file"}]
JSON
export INSTAINPAINT_MODELS_DIR=$WORK/cache INSTAINPAINT_MODELS_CATALOGUE=$WORK/catalogue.json
unset INSTAINPAINT_SEGMENTER INSTAINPAINT_INPAINTER
"$BIN" models import "$WORK/mobile_sam.pt" --as mobile-sam
"$BIN" models import "$WORK/big-lama.ckpt" --as big-lama
echo "machine: $(lscpu | sed -n 's/^Model name: *//p'), $(nproc) cores; $(git -C "$SEGMENTER_REPO" rev-parse --short HEAD); $(date -u +%F)"
echo "== the page, the reference painted by Navier-Stokes (--inpainter ns)"
"$SEGMENTER_REPO/scripts/measure-serve-edit.py" --bin "$BIN" --scene "$SCENE" --runs "$RUNS" --clicks 8 -- --inpainter ns
echo "== the page, the reference painted by LaMa (auto: the cache's)"
"$SEGMENTER_REPO/scripts/measure-serve-edit.py" --bin "$BIN" --scene "$SCENE" --runs "$RUNS" --clicks 8
echo "== the page's Fill of a million splats, the hole painted by LaMa (auto: the cache's)"
ROOM=$WORK/fill/rooms/scene_000
[ -f "$ROOM/scene.ply" ] || "$BIN" synth --out "$WORK/fill/rooms" --scenes 1 --seed 11 --views 24 --test-views 2 \
  --width 512 --height 512 --detail 1.6 --object procedural --save-gaussians --no-depth > /dev/null
BOX=$(python3 "$SEGMENTER_REPO/scripts/splat-bounds.py" "$ROOM/object.ply" --grow 1.1)
"$SEGMENTER_REPO/scripts/measure-serve-fill.py" --bin "$BIN" --ply "$ROOM/scene.ply" --box "$BOX" --runs "$RUNS" \
  -- --scene "$ROOM"
