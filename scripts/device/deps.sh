# Sourced by the scripts that run ON a lent GPU machine (bash, set -euo pipefail): makes the
# Debian libraries our binaries load available there (nothing can be installed on it), from
#   .device/debs/    the packages themselves (scripts/device/prepare.sh), for a build; or
#   .device/bundle/  a binary built there earlier with the libraries it loads (build-and-check.sh's
#                    bundle step), for a run without a build.
# Sets DEPS (the private prefix) and LD_LIBRARY_PATH, and for a build CMake's and pkg-config's
# search paths.
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
  export PKG_CONFIG=$DEPS/usr/bin/pkgconf
  export PKG_CONFIG_LIBDIR="$libs/pkgconfig:$DEPS/usr/share/pkgconfig" PKG_CONFIG_SYSROOT_DIR=$DEPS
}

# The bundle: instainpaint.tar.xz holding bin/instainpaint and lib/ (its Debian libraries).
# LibTorch and CUDA come from the machine's own PyTorch, which it was built against.
device_deps_from_bundle() {
  mkdir -p "$DEPS"
  tar -xJf .device/bundle/instainpaint.tar.xz -C "$DEPS"
  local torch_lib
  torch_lib=$(python3 -c 'import os, torch; print(os.path.dirname(torch.__file__))')/lib
  local cuda_lib
  cuda_lib=$(python3 -c 'import os, nvidia; print(os.path.dirname(nvidia.__path__[0]))')/nvidia/cu13/lib
  export LD_LIBRARY_PATH="$DEPS/lib:$torch_lib:$cuda_lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
  BIN=$DEPS/bin/instainpaint
}

# Writes the bundle of binary $1 to $2/instainpaint.tar.xz: the binary, stripped, and every library it
# loads from $DEPS.
device_make_bundle() {
  local stage=/tmp/instainpaint-bundle
  rm -rf "$stage"
  mkdir -p "$stage/bin" "$stage/lib"
  strip -o "$stage/bin/instainpaint" "$1"
  ldd "$1" | awk -v deps="$DEPS" 'index($3, deps) == 1 { print $3 }' | xargs -r cp -L -t "$stage/lib"
  tar -cJf "$2/instainpaint.tar.xz" -C "$stage" bin lib
  echo "bundle: $(du -h "$2/instainpaint.tar.xz" | cut -f1), $(ls "$stage/lib" | wc -l) libraries"
}
