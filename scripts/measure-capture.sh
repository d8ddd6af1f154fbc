#!/usr/bin/env bash
# `capture` against plain COLMAP on the same photos, in one run on this machine: each one's time
# (and its steps') and its poses against the photos' known poses.
#
#   scripts/measure-capture.sh PHOTOS|VIDEO REFERENCE_SCENE [OUT]
#
# PHOTOS: a folder of photos; REFERENCE_SCENE: a posed scene of the same photos (any format the
# readers take, views named as the photos), e.g. a SPIn-NeRF scene's poses_bounds.npy.
# VIDEO: a video file; every frame is posed by both (a user's `ffmpeg -i VIDEO frame_%04d.png` for
# plain COLMAP, `capture --frames <all of them>`), so REFERENCE_SCENE names its views
# frame_0001.png, ...
# Plain COLMAP is what a user would run by hand: Debian's colmap 3.8, its defaults (one camera
# for all photos), the sequential matcher, the incremental mapper. Results: OUT/results.json and
# a table on stdout.
set -euo pipefail
INPUT=$(realpath "${1:?a folder of photos or a video}")
REFERENCE=$(realpath "${2:?a posed scene of the same photos}")
OUT=${3:-capture-measure}
BIN=${BIN:-build/instainpaint}
rm -rf "$OUT"
mkdir -p "$OUT/plain/sparse"
OUT=$(realpath "$OUT")
now() { date +%s.%N; }
seconds() { echo "$2 - $1" | bc; }

PHOTOS=$INPUT CAPTURE_ARGS=()
t0=$(now)
if [ -f "$INPUT" ]; then  # a video: the user extracts its frames first (timed with plain COLMAP)
  PHOTOS=$OUT/plain/frames
  mkdir -p "$PHOTOS"
  ffmpeg -loglevel error -i "$INPUT" "$PHOTOS/frame_%04d.png"
  CAPTURE_ARGS=(--frames "$(ls "$PHOTOS" | wc -l)")
fi
echo "== plain COLMAP $(colmap -h 2>&1 | head -1 | awk '{print $2}') (sequential matcher) on $(ls "$PHOTOS" | wc -l) images"
colmap feature_extractor --database_path "$OUT/plain/db.db" --image_path "$PHOTOS" \
  --ImageReader.single_camera 1 --SiftExtraction.use_gpu 0 > "$OUT/plain/colmap.log" 2>&1
t1=$(now)
colmap sequential_matcher --database_path "$OUT/plain/db.db" --SiftMatching.use_gpu 0 >> "$OUT/plain/colmap.log" 2>&1
t2=$(now)
colmap mapper --database_path "$OUT/plain/db.db" --image_path "$PHOTOS" --output_path "$OUT/plain/sparse" \
  >> "$OUT/plain/colmap.log" 2>&1
t3=$(now)
# The largest model as a scene folder the readers take (sparse/0 + images/).
largest=$(for m in "$OUT"/plain/sparse/*/; do echo "$(colmap model_analyzer --path "$m" 2>&1 |
  grep -m1 'Registered images' | grep -o '[0-9]*$') $m"; done | sort -n | tail -1 | cut -d' ' -f2)
mkdir -p "$OUT/plain/scene/sparse"
ln -s "$largest" "$OUT/plain/scene/sparse/0"
ln -s "$PHOTOS" "$OUT/plain/scene/images"
"$BIN" scene-info --scene "$OUT/plain/scene" --compare "$REFERENCE" --json > "$OUT/plain/scene-info.json" 2> /dev/null

echo "== instainpaint capture"
"$BIN" capture "$INPUT" "${CAPTURE_ARGS[@]}" --out "$OUT/ours" --compare "$REFERENCE" 2>&1 | tee "$OUT/ours.log" | grep -v "COLMAP .*: [0-9]* of"

python3 - "$OUT" "$(seconds "$t0" "$t1")" "$(seconds "$t1" "$t2")" "$(seconds "$t2" "$t3")" <<'PY'
import json, sys
out, features, matching, mapping = sys.argv[1], *map(float, sys.argv[2:])
plain_info = json.load(open(f"{out}/plain/scene-info.json"))
ours = json.load(open(f"{out}/ours/capture.json"))
t = ours["timings"]
rows = {
    "plain COLMAP (sequential)": dict(features_s=features, matching_s=matching, mapping_s=mapping,
                                      total_s=features + matching + mapping, posed=len(plain_info["views"]),
                                      **plain_info["compared_with"]),
    f"instainpaint capture ({ours['matcher']})": dict(
        features_s=t["colmap_features_s"], matching_s=t["colmap_matching_s"], mapping_s=t["colmap_mapping_s"],
        total_s=t["total_s"], posed=ours["registered"], **ours["compared_with"]),
}
json.dump(rows, open(f"{out}/results.json", "w"), indent=2)
print(f"\n{'':34} {'features':>9} {'matching':>9} {'mapping':>9} {'total':>9} {'posed':>6} {'rot. median':>12} {'pos. median':>12}")
for name, r in rows.items():
    print(f"{name:34} {r['features_s']:8.0f}s {r['matching_s']:8.0f}s {r['mapping_s']:8.0f}s {r['total_s']:8.0f}s "
          f"{r['posed']:6d} {r['median_rotation_deg']:11.3f}° {100 * r['median_position']:11.2f}%")
print("(total: capture's whole command, with reading the photos, undistortion and writing; positions in % of the "
      "largest distance between two reference cameras)")
PY
