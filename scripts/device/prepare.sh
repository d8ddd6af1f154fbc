#!/usr/bin/env bash
# Run HERE (Debian 12), before using a lent GPU machine: the GPU machine can reach no package
# registry, so this gathers what its build needs into .device/ (git-ignored), which the
# device tool carries along (`carry: [".device"]`):
#   .device/debs/     the Debian packages of our build dependencies and the libraries they
#                     load that a CUDA image usually lacks (OpenCV's X11/GL/BLAS, TBB, ...)
#   .device/shared/   the ../shared fixtures and data the GPU tests and the refinement timing
#                     read (only the checkout travels, and ../shared does not)
#   .device/scenes/   the real scenes a default model trains on (scripts/device/train-default-model.sh)
#   .device/wheels/   nanobind's wheel, the version pyproject.toml pins (the Python module, STEPS=python)
#   .device/official/ with OFFICIAL=<mirror of dhmbb2/InstaInpaint>: its network code, for the
#                     host CPU's comparison (STEPS=cpu)
# Then, on the GPU machine: bash scripts/device/build-and-check.sh (see its header).
set -euo pipefail
cd "$(dirname "$0")/../.."
SHARED=${SHARED:-../shared}
DEST=.device

PACKAGES=(
  # headers and link-time libraries of the build
  nlohmann-json3-dev libcli11-dev libeigen3-dev libstb-dev
  libspdlog-dev libspdlog1.10 libfmt-dev libfmt9 libzip-dev libzip4
  libopencv-core-dev libopencv-core406 libopencv-imgproc-dev libopencv-imgproc406
  libopencv-calib3d-dev libopencv-calib3d406 libopencv-photo-dev libopencv-photo406
  libopencv-features2d-dev libopencv-features2d406 libopencv-flann-dev libopencv-flann406
  libgloo-dev  # Gloo's headers (CPU data-parallel training), which the machines' PyTorch lacks
  cimg-dev  # the patch inpainter's one header
  libgtest-dev libgmock-dev libbenchmark-dev libbenchmark1debian
  libcpp-httplib-dev libcpp-httplib0.11 libbrotli1 libssl3
  libwebp-dev libwebp7 libwebpmux3 libwebpdemux2 libzstd-dev libzstd1  # SPZ (zstd) and SOG (webp)
  pkgconf pkgconf-bin libpkgconf3  # the build finds cpp-httplib through pkg-config,
  libssl-dev zlib1g-dev libbrotli-dev  # whose .pc file requires theirs
  libcurl4-openssl-dev libcurl4 libnghttp2-14 librtmp1 libssh2-1 libpsl5 libldap-2.5-0 libsasl2-2 libsasl2-modules-db libgssapi-krb5-2 libkrb5-3 libk5crypto3 libkrb5support0 libkeyutils1 libcom-err2 libidn2-0 libunistring2  # models get (libcurl and what it loads)
  # what Debian's OpenCV 4.6 loads
  libtbb12 libopenblas0-pthread libgfortran5 libquadmath0 libglx0 libglvnd0
  libx11-6 libxcb1 libxau6 libxdmcp6 libbsd0 libmd0
)

mkdir -p "$DEST/debs"
rm -f "$DEST"/debs/*.deb
(cd "$DEST/debs" && apt-get download -qq "${PACKAGES[@]}")

rm -rf "$DEST/shared" "$DEST/scenes"
mkdir -p "$DEST/shared/fixtures" "$DEST/shared/data" "$DEST/scenes"
cp -r "$SHARED/fixtures/official-tiny" "$DEST/shared/fixtures/"
cp -r "$SHARED/data/render-golden" "$SHARED/data/statue" "$SHARED/data/lpips" "$DEST/shared/data/"
cp -r "$SHARED/data/fern" "$SHARED/data/fox" "$DEST/scenes/"
# Real captures with exact cameras for the default model's continuation (finetune-default-model.sh),
# in one folder so that a call carries them as one path: DTU (LLFF layout) and the four Strecha
# scenes made readable (nerfstudio), 8 MB.
rm -rf "$DEST/realtrain"
mkdir -p "$DEST/realtrain"
cp -r "$SHARED/data/realtrain/dtu_scan24" "$SHARED/data/realtrain/dtu_scan37" "$DEST/realtrain/"
for scene in "$SHARED"/data/realtrain/strecha_*; do
  python3 scripts/strecha-to-nerfstudio.py "$scene" "$DEST/realtrain/$(basename "$scene")" --copy-images
done

# The official network's code for the host CPU's comparison (build-and-check.sh STEPS=cpu), from a
# mirror of github.com/dhmbb2/InstaInpaint when OFFICIAL names one (a bare git directory or a work tree).
rm -rf "$DEST/official"
if [ -n "${OFFICIAL:-}" ]; then
  mkdir -p "$DEST/official"
  if [ -d "$OFFICIAL/instainpaint" ]; then cp -r "$OFFICIAL/instainpaint" "$DEST/official/"
  else git --git-dir="$OFFICIAL" archive HEAD instainpaint | tar -x -C "$DEST/official"; fi
fi

rm -rf "$DEST/wheels"
python3 -m pip download --quiet --disable-pip-version-check --no-deps --only-binary=:all: --dest "$DEST/wheels" \
  "$(grep -o 'nanobind==[0-9.]*' pyproject.toml)"

echo "prepare: $(ls "$DEST"/debs/*.deb | wc -l) packages, $(du -sh "$DEST" | cut -f1) in $DEST"
# The device tool carries at most 64 MiB, the checkout's tracked files included.
echo "a check call carries $(du -cm "$DEST/debs" "$DEST/shared" "$DEST/wheels" $(git ls-files) | tail -1 | cut -f1) MiB (limit 64)"
echo "carry it: run(command=\"bash scripts/device/build-and-check.sh\", carry=[\"$DEST/debs\", \"$DEST/shared\", \"$DEST/wheels\"])"
