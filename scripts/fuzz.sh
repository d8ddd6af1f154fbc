#!/usr/bin/env bash
# Runs the libFuzzer targets of the parsers (tests/fuzz) under ASan + UBSan.
#
#   scripts/fuzz.sh [--build DIR] [--seconds S] [TARGET ...]
#
#   --build DIR    the sanitizer build made with clang (default build-asan; `make fuzz` makes it)
#   --seconds S    fuzzing time per target (default 60)
#   TARGET         the targets to run (default: all that DIR holds)
#
# Each target starts from its corpus in DIR/fuzz-corpus/<target> (kept between runs), to
# which its hand-made seeds and the matching files of ../shared are added. It prints, per
# target, the executions run, libFuzzer's coverage (cov: edges reached) and the findings;
# an input that crashed, hung, leaked or tripped a sanitizer is kept in fuzz-findings/<target>/
# (emptied when the target runs again) and makes the script exit with 1.
# Environment: INSTAINPAINT_SHARED (default ../shared).
set -euo pipefail

root="$(cd "$(dirname "$0")/.." && pwd)"
build="$root/build-asan"
seconds=60
targets=()
while [ $# -gt 0 ]; do
  case "$1" in
    --build) build="$(cd "$2" && pwd)"; shift 2 ;;
    --seconds) seconds="$2"; shift 2 ;;
    -h|--help) sed -n '2,15p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    -*) echo "fuzz.sh: unknown option $1 (see --help)" >&2; exit 2 ;;
    *) targets+=("$1"); shift ;;
  esac
done
shared="${INSTAINPAINT_SHARED:-$root/../shared}"
bin="$build/tests"
if [ ${#targets[@]} -eq 0 ]; then
  for f in "$bin"/fuzz_*; do
    [ -x "$f" ] && [ "$(basename "$f")" != fuzz_regression_test ] && targets+=("${f##*/fuzz_}")
  done
fi
if [ ${#targets[@]} -eq 0 ]; then
  echo "fuzz.sh: no fuzz executables in $bin (build with clang: make fuzz)" >&2
  exit 2
fi

# Files of ../shared each target starts from (missing ones are skipped).
shared_seeds() {
  case "$1" in
    npy|llff) echo data/statue/poses_bounds.npy data/fern/poses_bounds.npy ;;
    ply) echo data/splats/guitar.compressed.ply data/splats/biker.compressed.ply ;;
    safetensors) echo data/lpips/alex.safetensors data/lpips/vgg.safetensors data/render-golden/tiny_case.safetensors ;;
    pth) echo fixtures/official-tiny/checkpoint.pth ;;
    nerfstudio) echo data/fox/transforms.json ;;
    image) echo data/lpips/imgs/ex_ref.png data/lpips/imgs/ex_p0.png data/statue/images_2/label/IMG_2707.png ;;
    mask_folder) echo data/statue/images_2/label/IMG_2707.png ;;
  esac
}
# Longest input per target: large enough for the seeds that matter (whole checkpoints for pth).
max_len() {
  case "$1" in
    pth) echo 3000000 ;;
    ply) echo 200000 ;;
    *) echo 65536 ;;
  esac
}

# The targets write each input to a file: in memory where there is a tmpfs.
[ -d /dev/shm ] && [ -w /dev/shm ] && export TMPDIR=/dev/shm
status=0
total=0
printf '%-14s %10s %8s %8s  %s\n' target executions exec/s cov findings
for t in "${targets[@]}"; do
  exe="$bin/fuzz_$t"
  if [ ! -x "$exe" ]; then echo "fuzz.sh: no target $t ($exe)" >&2; status=1; continue; fi
  corpus="$build/fuzz-corpus/$t"
  findings="$root/fuzz-findings/$t"
  rm -rf "$findings"
  mkdir -p "$corpus" "$findings"
  II_FUZZ_WRITE_SEEDS="$corpus" "$exe" > /dev/null 2>&1
  for f in $(shared_seeds "$t"); do
    [ -f "$shared/$f" ] && cp -f "$shared/$f" "$corpus/shared-$(echo "$f" | tr / _)"
  done
  case "$t" in
    colmap_binary|colmap_text)
      ext=bin; [ "$t" = colmap_text ] && ext=txt
      k=0
      for stem in cameras images points3D; do
        for f in "$shared"/data/*/sparse/0/$stem.$ext "$shared"/data/*/$stem.$ext; do
          [ -f "$f" ] && [ "$(stat -c %s "$f")" -le 65535 ] &&
            { printf "\\x0$k"; cat "$f"; } > "$corpus/shared-$k-$(echo "$f" | md5sum | cut -c1-8)"
        done
        k=$((k + 1))
      done ;;
    pickle)
      # the official fixture's pickle, out of its zip
      ckpt="$shared/fixtures/official-tiny/checkpoint.pth"
      if [ -f "$ckpt" ] && command -v unzip > /dev/null; then
        name=$(unzip -Z1 "$ckpt" | grep 'data.pkl$' | head -1)
        [ -n "$name" ] && unzip -p "$ckpt" "$name" > "$corpus/shared-checkpoint-data.pkl"
      fi ;;
  esac
  log="$build/fuzz-$t.log"
  set +e
  ASAN_OPTIONS=detect_leaks=1:allocator_may_return_null=1 UBSAN_OPTIONS=print_stacktrace=1 \
    "$exe" -max_total_time="$seconds" -print_final_stats=1 -timeout=10 -rss_limit_mb=2560 \
    -max_len="$(max_len "$t")" -artifact_prefix="$findings/" "$corpus" > "$log" 2>&1
  rc=$?
  set -e
  execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' || true)
  speed=$(grep -o 'stat::average_exec_per_sec: *[0-9]*' "$log" | grep -o '[0-9]*$' || true)
  cov=$(grep -o 'cov: [0-9]*' "$log" | tail -1 | grep -o '[0-9]*' || true)
  found=$(find "$findings" -type f | wc -l)
  note="none"
  if [ "$rc" -ne 0 ] || [ "$found" -gt 0 ]; then
    status=1
    note="$found in fuzz-findings/$t (exit $rc; log $log)"
    grep -m1 -E 'ERROR: |runtime error|terminate called|Uncaught' "$log" | sed 's/^/    /' || true
  fi
  printf '%-14s %10s %8s %8s  %s\n' "$t" "${execs:-?}" "${speed:-?}" "${cov:-?}" "$note"
  total=$((total + ${execs:-0}))
done
echo "total executions: $total"
exit $status
