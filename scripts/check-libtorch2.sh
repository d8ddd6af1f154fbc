#!/usr/bin/env bash
# Builds instainpaint against LibTorch 2.x and runs every test with it, on the CPU.
# Debian 13 (trixie) packages LibTorch 2.6, so a trixie root made with debootstrap runs the
# 2.x side of src/common/torch_compat.h for real (fused attention, the c10d Backend
# classes) without a GPU machine. The root is kept between runs: a second run only rebuilds.
#
# Usage: scripts/check-libtorch2.sh [ROOT]      (root; ROOT defaults to ../libtorch2-root)
# Needs: deb.debian.org reachable; ../shared beside the repository, as for `make test`.
set -euo pipefail

repo=$(cd "$(dirname "$0")/.." && pwd)
shared="$repo/../shared"
root=${1:-$repo/../libtorch2-root}

if [ "$(id -u)" -ne 0 ]; then
  echo "check-libtorch2: needs root (debootstrap, mount, chroot)" >&2
  exit 1
fi
if [ ! -d "$shared" ]; then
  echo "check-libtorch2: $shared not found (the tests read their data there)" >&2
  exit 1
fi
command -v debootstrap > /dev/null || {
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends debootstrap
}

if [ ! -x "$root/usr/bin/apt-get" ]; then
  echo "check-libtorch2: creating a Debian 13 root in $root"
  debootstrap --variant=minbase trixie "$root" http://deb.debian.org/debian
fi
cp /etc/resolv.conf "$root/etc/resolv.conf"

mounted=()
bind() {  # bind SOURCE TARGET-inside-root
  mkdir -p "$root$2"
  mount --bind "$1" "$root$2"
  mounted=("$root$2" "${mounted[@]}")
}
cleanup() {
  for m in "${mounted[@]}"; do umount "$m" || true; done
}
trap cleanup EXIT
bind /proc /proc
bind /dev /dev
bind "$repo" /w/main
bind "$(cd "$shared" && pwd)" /w/shared

# The same dependency script as on Debian 12; the build lives in the root, not the checkout.
chroot "$root" /bin/bash -c '
  set -euo pipefail
  cd /w/main
  bash scripts/install-deps.sh
  cmake -S . -B /build -G Ninja -DCMAKE_BUILD_TYPE=Release > /dev/null
  cmake --build /build -j "$(nproc)"
  echo "check-libtorch2: built against LibTorch $(grep -oP "(?<=TORCH_VERSION_(MAJOR|MINOR|PATCH) )[0-9]+" /usr/include/torch/csrc/api/include/torch/version.h | paste -sd.)"
  cd /build && ctest --output-on-failure -j "$(nproc)"'
