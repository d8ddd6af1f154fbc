#!/usr/bin/env bash
# Installs the Debian 12 packages instainpaint needs to build, test and run.
# Idempotent: packages already present are skipped, so a second run is instant.
set -euo pipefail

PACKAGES=(
  build-essential cmake ninja-build ccache
  clang                         # the sanitizer build and its libFuzzer targets
  libclang-rt-14-dev            # clang's sanitizer and libFuzzer runtimes (clang only recommends it)
  libtorch-dev
  libopenblas0-pthread          # without it LibTorch falls back to reference BLAS (~60x slower)
  nlohmann-json3-dev libcli11-dev libspdlog-dev libfmt-dev
  libstb-dev libzip-dev zlib1g-dev libzstd-dev libwebp-dev libeigen3-dev
  libnanoflann-dev              # reconstruct: each start point's nearest neighbours (its first scale)
  libssl-dev                    # SHA-256 of model files (run.json)
  libcurl4-openssl-dev          # instainpaint models get (HTTPS downloads)
  libopencv-imgproc-dev libopencv-features2d-dev libopencv-calib3d-dev libopencv-photo-dev
  cimg-dev                      # the patch inpainter (fill's built-in reference): one header
  libgtest-dev libgmock-dev libbenchmark-dev
  libgloo-dev
  ffmpeg                        # videos out (render, serve) and in (capture)
  colmap                        # capture: poses photos and video frames (CPU SIFT and mapping)
  libcpp-httplib-dev            # serve
  chromium                      # the browser tests of serve's page (headless, software WebGL)
  python3-dev python3-venv      # the Python package (pip install .; its tests in .venv-py)
  python3-numpy python3-torch   # ... its arrays, and Debian's torch on the same LibTorch, side by side
)
# Node.js and npm bundle the page (web/); a machine that has them (e.g. from NodeSource) keeps its own.
command -v node > /dev/null || PACKAGES+=(nodejs)
command -v npm > /dev/null || PACKAGES+=(npm)

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done

if [ ${#missing[@]} -gt 0 ]; then
  echo "install-deps: installing ${missing[*]}"
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

# The page's npm packages, exactly as web/package-lock.json pins them (again when it changes).
WEB=$(dirname "$0")/../web
if [ ! -f "$WEB/node_modules/.package-lock.json" ] || [ "$WEB/package-lock.json" -nt "$WEB/node_modules/.package-lock.json" ]; then
  echo "install-deps: npm ci in web/"
  (cd "$WEB" && npm ci --no-audit --no-fund --loglevel=error)
fi
