#!/usr/bin/env bash
# Run ON a lent GPU machine: continues training the embedded default model (preset `mini`,
# models/default.safetensors) in bf16, first at 128 x 128 (the model card's rooms), then at
# 256 x 256 (where the statue is judged and `mini` never trained). Starting from the embedded
# model, a short call can only add to it; a 10 M `medium` model from scratch needed far more
# than one call (2026-11-25, docs/benchmarks.md, "Not kept"). Data as the model card's: synthetic rooms
# (seed 1001), the validation rooms (seed 777001), the real fern and statue when carried (fox is left
# out to fit the 64 MiB a call carries), and the real captures of .device/realtrain when carried
# (DTU scans 24 and 37, the four Strecha scenes: exact cameras; measured 2026-11-27, the Strecha
# ones move SPIn-NeRF scene 1 and the fern on the CPU); the real captures' depth is supervised at
# points triangulated from their photos (train --depth-from-photos). The judging happens afterwards on any machine
# (scripts/measure-refinement.sh --steps 0 with --checkpoint). Writes to $OUT:
#   model-128.safetensors, model-256.safetensors  each phase's model (the 256 one updated while it trains)
#   train.log, log-128.jsonl, log-256.jsonl
# Here, before: scripts/device/prepare.sh; then
#   run(command="bash scripts/device/finetune-default-model.sh",
#       carry=[".device/debs", ".device/shared/data/statue", ".device/scenes/fern", ".device/realtrain"],
#       timeout_s=590)
# Environment: STEPS_128, STEPS_256 (steps of each phase), SECONDS_128, SECONDS_256 (each phase is
# stopped after this long; its last checkpoint counts), ROOMS, WORKERS, PHASES ("128 256", or one
# of them: the 256 phase then starts from the embedded model), REAL_REPEAT (each real scene listed
# this many times: a sample draws scenes uniformly, so this weighs real photos against the rooms),
# OWN_VIEW_WEIGHT (train --own-view-weight, default 0: each input's own Gaussians at its own
# camera against its photo; measured 2026-11-28 on 2 CPU cores at 128²: 1 raised the rooms' own views
# 23.2 → 27.9 dB but lost 1.1 dB masked, so try it where the issue's own-views target is judged);
# PHASES="cycle" trains at the sizes of SIZE_CYCLE in turn, one per step (train --size-cycle,
# default 128,128,128,256; STEPS_CYCLE, SECONDS_CYCLE; model-cycle.safetensors): a CPU run
# (2026-11-28) kept the rooms at 128² within 0.4 dB where the 256 phase after the 128 one lost 2.8.
set -euo pipefail
cd "$(dirname "$0")/../.."
OUT=${OUT:-$PWD/device-out}
STEPS_128=${STEPS_128:-250}
STEPS_256=${STEPS_256:-450}
SECONDS_128=${SECONDS_128:-110}
SECONDS_256=${SECONDS_256:-140}
ROOMS=${ROOMS:-64}
WORKERS=${WORKERS:-12}
PHASES=${PHASES:-"128 256"}
REAL_REPEAT=${REAL_REPEAT:-1}
OWN_VIEW_WEIGHT=${OWN_VIEW_WEIGHT:-0}
SIZE_CYCLE=${SIZE_CYCLE:-128,128,128,256}
STEPS_CYCLE=${STEPS_CYCLE:-400}
SECONDS_CYCLE=${SECONDS_CYCLE:-250}
WORK=/tmp/ii-finetune
mkdir -p "$OUT" "$WORK"
exec > >(tee -a "$OUT/train.log") 2>&1
step() { printf '\n== %s (%s)\n' "$*" "$(date +%T)"; }

source scripts/device/deps.sh
device_deps_from_debs
device_build_program_and_rooms "$OUT" "$WORK" "$ROOMS" 256
SCENES="$WORK/train"
# Each real scene that was carried (a call that carries the GPU check's packages too leaves the fern out).
REAL=""
for scene in .device/scenes/fern .device/shared/data/statue .device/realtrain/*/; do
  [ -d "$scene" ] && REAL+="${REAL:+,}${scene%/}"
done
[ -n "$REAL" ] && for _ in $(seq "$REAL_REPEAT"); do SCENES+=",$REAL"; done
echo "training scenes: $SCENES"

# The phase's model goes to $OUT while it trains: a call cut short still brings one back.
phase() {  # size ("cycle": SIZE_CYCLE) batch steps seconds lr init
  local size=$1 batch=$2 steps=$3 seconds=$4 lr=$5 init=$6 run="$WORK/run-$1"
  local size_args=(--width "$size" --height "$size")
  [ "$size" = cycle ] && size_args=(--size-cycle "$SIZE_CYCLE")
  local label="$size x $size"
  [ "$size" = cycle ] && label="the sizes $SIZE_CYCLE in turn"
  step "phase at $label: $steps steps, batch $batch, peak lr $lr, at most $seconds s"
  ( while sleep 15; do [ -f "$run/model.safetensors" ] && cp "$run/model.safetensors" "$OUT/model-$size.safetensors.tmp" &&
      mv "$OUT/model-$size.safetensors.tmp" "$OUT/model-$size.safetensors"; done ) &
  local copier=$!
  timeout "$seconds" "$BIN" train --scenes "$SCENES" \
    --val-scenes "$WORK/val" --out "$run" --stage inpaint --init "$init" "${size_args[@]}" \
    --inputs 4 --targets 4 --batch "$batch" --steps "$steps" --lr "$lr" --warmup 30 --depth-weight 0.2 --depth-from-photos --own-view-weight "$OWN_VIEW_WEIGHT" \
    --device cuda --precision bf16 --workers "$WORKERS" --val-every 100000 --val-samples 12 --save-every 50 \
    --log-every 25 || echo "phase $size stopped early (status $?)"
  kill "$copier" || true
  cp "$run/model.safetensors" "$OUT/model-$size.safetensors"
  cp "$run/log.jsonl" "$OUT/log-$size.jsonl"
}
init=models/default.safetensors
if [[ " $PHASES " == *" 128 "* ]]; then
  phase 128 16 "$STEPS_128" "$SECONDS_128" 3e-4 "$init"
  init=$WORK/run-128/model.safetensors
fi
[[ " $PHASES " == *" 256 "* ]] && phase 256 8 "$STEPS_256" "$SECONDS_256" 2e-4 "$init"
[[ " $PHASES " == *" cycle "* ]] && phase cycle 8 "$STEPS_CYCLE" "$SECONDS_CYCLE" 2e-4 "$init"
step "done"
