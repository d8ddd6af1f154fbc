# Sourced by the scripts that run ON a lent GPU machine (bash, set -euo pipefail): makes the
# Debian packages of our build (.device/debs/, from scripts/device/prepare.sh) available there,
# where nothing can be installed: unpacked into DEPS, with LD_LIBRARY_PATH and CMake's and
# pkg-config's search paths pointing into it.
DEPS=/opt/instainpaint-deps
device_deps_from_debs() {
  [ -d .device/debs ] || { echo "no .device/debs: run scripts/device/prepare.sh here and carry .device"; exit 2; }
  mkdir -p "$DEPS"
  local f
  for f in .device/debs/*.deb; do
    if command -v dpkg-deb > /dev/null; then
      dpkg-deb -x "$f" "$DEPS"
    else  # a .deb is an ar archive holding data.tar.xz (Debian 12)
      ar p "$f" data.tar.xz | tar -xJ -C "$DEPS"
    fi
  done
  local libs="$DEPS/usr/lib/x86_64-linux-gnu"
  # Debian's OpenCV loads BLAS/LAPACK through alternatives that dpkg-deb -x does not set up.
  export LD_LIBRARY_PATH="$libs:$libs/openblas-pthread:$DEPS/lib/x86_64-linux-gnu${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
  export CMAKE_PREFIX_PATH="$DEPS/usr${CMAKE_PREFIX_PATH:+:$CMAKE_PREFIX_PATH}"
  # libraries linked by name (-lzstd, -lwebp, -lz) are found by the compiler driver here
  export LIBRARY_PATH="$libs${LIBRARY_PATH:+:$LIBRARY_PATH}"
  export PKG_CONFIG=$DEPS/usr/bin/pkgconf
  export PKG_CONFIG_LIBDIR="$libs/pkgconfig:$DEPS/usr/share/pkgconfig" PKG_CONFIG_SYSROOT_DIR=$DEPS
}

# The training scripts' common start (after device_deps_from_debs): the program alone built in
# build-gpu (about 2 minutes on 16 cores; the log in $OUT/build.log), then the model card's
# training rooms (seed 1001) and validation rooms (6, seed 777001) at SIZE x SIZE into WORK/train
# and WORK/val. Sets BIN.
device_build_program_and_rooms() {  # OUT WORK ROOMS SIZE
  local out=$1 work=$2 rooms=$3 size=$4
  JOBS=$(nproc) bash scripts/gpu/build.sh --python python3 --build build-gpu --cuda-arch 9.0 \
    --target instainpaint > "$out/build.log" 2>&1 || { tail -40 "$out/build.log"; exit 1; }
  BIN=build-gpu/instainpaint
  nvidia-smi --query-gpu=name,memory.total --format=csv,noheader || true
  printf '\n== training rooms (%s, seed 1001) and validation rooms (6, seed 777001) at %s x %s (%s)\n' \
    "$rooms" "$size" "$size" "$(date +%T)"
  "$BIN" synth --out "$work/train" --scenes "$rooms" --seed 1001 --views 20 --test-views 4 --width "$size" \
    --height "$size" --degrade mixed --threads "$(nproc)" 2>&1 | tail -1
  "$BIN" synth --out "$work/val" --scenes 6 --seed 777001 --views 20 --test-views 4 --width "$size" \
    --height "$size" --degrade mixed --threads "$(nproc)" 2>&1 | tail -1
}
