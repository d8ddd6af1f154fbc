#!/usr/bin/env bash
# Fill the hole on real captures: the statue and the fern, each refined into a splat
# scene with its object kept (infer --keep-object --refine, every 8th view held out), then an
# object removed with one stroke on one view and filled (fill --view --mask). Writes, per scene,
# held-out views before and after (compare.png: a row each) and an orbit of the filled scene.
#
# Usage: scripts/fill-real-scenes.sh [--bin build/instainpaint] [--shared ../shared] [--work DIR]
#        [--refine fast] [--height 256]
set -euo pipefail
BIN=build/instainpaint
SHARED=../shared
WORK=fill-real
REFINE=fast
HEIGHT=256
while [ $# -gt 0 ]; do
  case "$1" in
    --bin) BIN=$2; shift 2 ;;
    --shared) SHARED=$2; shift 2 ;;
    --work) WORK=$2; shift 2 ;;
    --refine) REFINE=$2; shift 2 ;;
    --height) HEIGHT=$2; shift 2 ;;
    -h|--help) sed -n '2,9p' "$0"; exit 0 ;;
    *) echo "unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
done
say() { echo "fill-real-scenes: $*" >&2; }
mkdir -p "$WORK"

# A white disk on black (a stroke) at the size of IMAGE, centred at fractions (fx, fy), radius a
# fraction of the height: a PNG written with the standard library alone.
disk_mask() {  # disk_mask IMAGE OUT fx fy r
  python3 - "$@" <<'EOF'
import struct, sys, zlib
image, out, fx, fy, r = sys.argv[1], sys.argv[2], *map(float, sys.argv[3:6])
w, h = struct.unpack(">II", open(image, "rb").read()[16:24])
cx, cy, rad = fx * w, fy * h, r * h
rows = b"".join(b"\0" + bytes(255 if (x - cx) ** 2 + (y - cy) ** 2 <= rad * rad else 0 for x in range(w)) for y in range(h))
chunk = lambda kind, data: struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
open(out, "wb").write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 0, 0, 0, 0)) +
                      chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b""))
EOF
}

# scene, the view to draw on, its mask, what to look from: "--hold-out-every 8 --test-views" (held-out
# views, a scene with masks) or "--views A,B" (input views: a scene without masks holds none out)
fill_scene() {
  local name=$1 scene=$2 view=$3 mask=$4 look=$5
  local hold=""
  case "$look" in --hold-out-every*) hold="--hold-out-every 8" ;; esac
  local out="$WORK/$name"
  mkdir -p "$out"
  say "$name: the capture refined into splats, object kept ($REFINE)"
  [ -f "$out/scene/gaussians.ply" ] || "$BIN" infer --scene "$scene" --keep-object $hold --height "$HEIGHT" \
    --refine "$REFINE" --out "$out/scene" > "$out/infer.log" 2>&1
  say "$name: one stroke on $view, removed and filled"
  "$BIN" fill "$out/scene/gaussians.ply" --scene "$scene" --view "$view" --mask "$mask" --height "$HEIGHT" \
    --out "$out/filled.ply" > "$out/fill.log" 2>&1
  tail -1 "$out/fill.log"
  for ply in scene/gaussians filled; do
    "$BIN" render --ply "$out/$ply.ply" --scene "$scene" $look --height "$HEIGHT" --no-video \
      --out "$out/held-out-$(basename $ply)" > /dev/null 2>&1
  done
  "$BIN" render --ply "$out/filled.ply" --scene "$scene" --trajectory orbit --frames 48 --height "$HEIGHT" \
    --out "$out/orbit" > /dev/null 2>&1 || say "$name: no orbit video (ffmpeg?)"
  # Held-out views: before (top row) and after (bottom row).
  local inputs=() n=0
  for frame in "$out"/held-out-gaussians/rgb/*.png; do
    inputs+=(-i "$frame" -i "$out/held-out-filled/rgb/$(basename "$frame")")
    n=$((n + 1))
  done
  local top="" bottom=""
  for k in $(seq 0 $((n - 1))); do top+="[$((2 * k)):v]"; bottom+="[$((2 * k + 1)):v]"; done
  ffmpeg -loglevel error -y "${inputs[@]}" -filter_complex \
    "${top}hstack=inputs=$n[t];${bottom}hstack=inputs=$n[b];[t][b]vstack=inputs=2,format=rgb24" "$out/compare.png"
  say "$name: $out/compare.png (held-out views, before above after), $out/filled-fill/compare.png (the fill's cameras)"
}

statue="$SHARED/data/statue"
fill_scene statue "$statue" IMG_2712 "$statue/images_2/label/IMG_2712.png" "--hold-out-every 8 --test-views"
fern="$SHARED/data/fern"
first=$(ls "$fern"/images_8/*.png | sed -n 5p)
disk_mask "$first" "$WORK/fern-stroke.png" 0.42 0.45 0.12
fill_scene fern "$fern" "$(basename "$first" .png)" "$WORK/fern-stroke.png" "--views image008,image016"
