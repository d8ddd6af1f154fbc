#!/usr/bin/env bash
# A smoke run of every subcommand of the executable, each on a tiny synthetic room: the check of
# the commands that both LibTorch builds run (the PyPI build runs only the tests whose code can
# differ between the versions, tests/pypi_build.list, plus this). It checks that each command
# starts, does its work and writes what it says; the tests of each folder check the results.
#   tests/smoke/every_command.sh BUILD/instainpaint
set -euo pipefail
exe=$(realpath "$1")
click_inside="$(dirname "$(realpath "$0")")/../../scripts/click-inside.py"
work=$(mktemp -d "${TMPDIR:-/tmp}/instainpaint-smoke-XXXXXX")
trap 'rm -rf "$work"' EXIT
cd "$work"
step() {
  local name=$1
  shift
  local start=$SECONDS
  if ! "$@" > "$name.log" 2>&1; then
    echo "smoke: '$name' failed: $*"
    tail -n 30 "$name.log"
    exit 1
  fi
  echo "smoke: $name ($((SECONDS - start)) s)"
}
expect_file() { [ -s "$1" ] || { echo "smoke: $1 was not written"; exit 1; }; }

# Every subcommand answers --help (capture's work is COLMAP's, torch-free and tested in capture/).
for command in scene-info capture prepare masks infer fill convert render synth bench metrics eval train serve segment inpaint models; do
  "$exe" "$command" --help > /dev/null || { echo "smoke: '$command --help' failed"; exit 1; }
done

# The networks' catalogue and an empty cache of the run's own (nothing is downloaded here).
export INSTAINPAINT_MODELS_DIR="$work/models"
step models-list "$exe" models list
step models-list-json "$exe" models list --json
step synth "$exe" synth --out rooms --scenes 1 --seed 3 --views 6 --test-views 1 --width 64 --height 48 \
  --object procedural --degrade none --threads 1
scene=rooms/scene_000
view=view_000
step scene-info "$exe" scene-info --scene "$scene" --json
step prepare "$exe" prepare --scene "$scene" --height 48 --out prepare
step infer "$exe" infer --scene "$scene" --height 48 --out infer
expect_file infer/gaussians.ply
step infer-keep-object "$exe" infer --scene "$scene" --height 48 --keep-object --out keep
step render "$exe" render --ply infer/gaussians.ply --scene "$scene" --height 48 --out render
step convert "$exe" convert infer/gaussians.ply infer/gaussians.spz
expect_file infer/gaussians.spz
step masks "$exe" masks --scene "$scene" --view "$view" --mask "$scene/images_4/label/$view.png" --height 48 --out masks
step fill "$exe" fill keep/gaussians.ply --scene "$scene" --view "$view" --mask "$scene/images_4/label/$view.png" --out filled.ply
expect_file filled.ply
# The click forms: the pixel deepest inside the view's mask, where a user would click.
click=$(python3 "$click_inside" "$scene/images_4/label/$view.png")
step masks-click "$exe" masks --scene "$scene" --view "$view" --click "$click" --height 48 --out masks-click
expect_file masks-click/masks.json
step fill-click "$exe" fill keep/gaussians.ply --scene "$scene" --view "$view" --click "$click" --out filled-click.ply
expect_file filled-click.ply
first=$(find render -name "*.png" | sort | head -n 1)
expect_file "$first"
step metrics "$exe" metrics "$first" "$first"
step eval "$exe" eval --scene "$scene" --height 48 --out eval
expect_file eval/metrics.json
step bench "$exe" bench --presets tiny --sizes 32 --repeat 1
step train "$exe" train --scenes rooms --stage inpaint --preset tiny --width 32 --height 32 --inputs 4 --targets 2 \
  --steps 1 --val-every 0 --perceptual ssim --threads 1 --out train
expect_file train/model.safetensors

# serve: starts, says where, and stops on SIGTERM.
"$exe" serve --port 0 --ply infer/gaussians.ply --out serve > serve.log 2>&1 &
server=$!
for _ in $(seq 1 300); do
  grep -q "open http://127.0.0.1" serve.log && break
  kill -0 "$server" 2> /dev/null || { echo "smoke: serve exited"; cat serve.log; exit 1; }
  sleep 0.1
done
grep -q "open http://127.0.0.1" serve.log || { echo "smoke: serve did not say where it listens"; cat serve.log; exit 1; }
kill -TERM "$server"
wait "$server" || true
echo "smoke: serve"
echo "smoke: every command ran"
