#!/usr/bin/env bash
# Compressed splat formats against the float PLY, for splat PLYs that `infer` wrote:
# each converted to SPZ, SOG and compressed PLY (`instainpaint convert`: write time), converted
# back (read time), its bytes per Gaussian and ratio to the PLY, and the PSNR of its renders
# against the PLY's renders from every camera of the PLY's scene (`render --scene`: infer writes the scene's frame).
#
#   scripts/measure-splat-formats.sh [--bin build/instainpaint] [--out splat-formats] PLY=SCENE ...
#   e.g. scripts/measure-splat-formats.sh demo-out/inpainted/gaussians.ply=demo-out/data/scene_000
# Prints one tab-separated row per file and format (also OUT/results.tsv).
set -euo pipefail
BIN=build/instainpaint OUT=splat-formats
CASES=()
while [ $# -gt 0 ]; do
  case "$1" in
    --bin) BIN=$2; shift 2 ;;
    --out) OUT=$2; shift 2 ;;
    -h|--help) sed -n '2,9p' "$0"; exit 0 ;;
    -*) echo "unknown option $1 (see --help)" >&2; exit 2 ;;
    *) CASES+=("$1"); shift ;;
  esac
done
[ ${#CASES[@]} -gt 0 ] || { echo "give at least one PLY=SCENE (see --help)" >&2; exit 2; }
mkdir -p "$OUT"
printf 'ply\tformat\tsplats\tbytes_per_splat\tratio\twrite_ms\tread_ms\tpsnr_db\tmin_psnr_db\n' > "$OUT/results.tsv"

# psnr A_DIR B_DIR: mean and minimum PSNR over the PNGs the two folders share.
psnr() {
  local sum=0 n=0 min=1000 p
  for a in "$1"/*.png; do
    p=$("$BIN" metrics "$a" "$2/$(basename "$a")" --json | python3 -c 'import json,sys; v=json.load(sys.stdin)["psnr"]; print(99 if v=="inf" else v)')
    sum=$(python3 -c "print($sum + $p)"); n=$((n + 1))
    min=$(python3 -c "print(min($min, $p))")
  done
  python3 -c "print(f'{$sum / $n:.2f}\t{$min:.2f}')"
}

for case in "${CASES[@]}"; do
  ply=${case%%=*} scene=${case#*=}
  name=$(basename "$(dirname "$ply")")-$(basename "$ply" .ply)
  work="$OUT/$name"
  mkdir -p "$work"
  "$BIN" render --splats "$ply" --scene "$scene" --no-video --out "$work/render-ply" > "$work/render-ply.log" 2>&1
  ply_bytes=$(stat -c %s "$ply")
  for format in spz sog compressed.ply; do
    file="$work/gaussians.$format"
    # "... read R ms, write W ms" from convert's summary line.
    "$BIN" convert "$ply" "$file" > "$work/write-$format.log"
    write_ms=$(sed -n 's/.*write \([0-9.]*\) ms.*/\1/p' "$work/write-$format.log")
    "$BIN" convert "$file" "$work/back-$format.ply" > "$work/read-$format.log"
    read_ms=$(sed -n 's/.*; read \([0-9.]*\) ms.*/\1/p' "$work/read-$format.log")
    splats=$(sed -n 's/.*(\([0-9]*\) splats.*/\1/p' "$work/write-$format.log")
    bytes=$(stat -c %s "$file")
    "$BIN" render --splats "$file" --scene "$scene" --no-video --out "$work/render-$format" > "$work/render-$format.log" 2>&1
    quality=$(psnr "$work/render-ply/rgb" "$work/render-$format/rgb")
    row=$(python3 -c "print(f'$ply\t$format\t$splats\t{$bytes / $splats:.1f}\t{$ply_bytes / $bytes:.2f}\t$write_ms\t$read_ms')")
    printf '%s\t%s\n' "$row" "$quality" | tee -a "$OUT/results.tsv"
  done
done
