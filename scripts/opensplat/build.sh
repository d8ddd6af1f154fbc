#!/usr/bin/env bash
# Builds OpenSplat (github.com/pierotofy/OpenSplat), CPU-only, against the LibTorch this project
# builds with, outside the repository, as the peer that scripts/opensplat/compare.sh measures
# `instainpaint reconstruct` against. Nothing of it is copied into the repository.
#
#   scripts/opensplat/build.sh BUILD_DIR            clones OpenSplat and its three header libraries
#   scripts/opensplat/build.sh BUILD_DIR --from DIR where DIR holds OpenSplat/, json/, nanoflann/
#                                                   and cxxopts/ checkouts (a machine offline)
# Prints the path of the opensplat executable. About 3 minutes on 2 cores.
set -euo pipefail
OPENSPLAT_COMMIT=15b7e80   # the commit measured in docs/benchmarks.md
JSON_TAG=v3.11.3; NANOFLANN_TAG=v1.5.5; CXXOPTS_TAG=v3.2.0   # the tags its CMakeLists asks for

if [[ $# -lt 1 || $1 == -h || $1 == --help ]]; then sed -n 2,9p "$0"; exit 2; fi
build=$(realpath -m "$1"); shift
from=""
if [[ ${1:-} == --from ]]; then from=$(realpath "$2"); fi
mkdir -p "$build"
src=$build/src
checkout() {  # name url ref
  local dir=$src/$1
  if [[ ! -d $dir/.git ]]; then
    if [[ -n $from ]]; then git clone -q "$from/$1" "$dir"; else git clone -q "$2" "$dir"; fi
  fi
  git -C "$dir" -c advice.detachedHead=false checkout -q "$3"
}
checkout OpenSplat https://github.com/pierotofy/OpenSplat "$OPENSPLAT_COMMIT"
checkout json https://github.com/nlohmann/json "$JSON_TAG"
checkout nanoflann https://github.com/jlblancoc/nanoflann "$NANOFLANN_TAG"
checkout cxxopts https://github.com/jarro2783/cxxopts "$CXXOPTS_TAG"

# Debian's libtorch-dev (the README's default) or the project's PyPI torch.
torch_dir=""
for d in /usr/share/cmake/Torch /usr/lib/x86_64-linux-gnu/cmake/Torch; do [[ -f $d/TorchConfig.cmake ]] && torch_dir=$d; done
cmake -S "$src/OpenSplat" -B "$build/build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DGPU_RUNTIME=CPU \
  ${torch_dir:+-DTorch_DIR=$torch_dir} \
  -DFETCHCONTENT_SOURCE_DIR_NLOHMANN_JSON="$src/json" \
  -DFETCHCONTENT_SOURCE_DIR_NANOFLANN="$src/nanoflann" \
  -DFETCHCONTENT_SOURCE_DIR_CXXOPTS="$src/cxxopts" >"$build/configure.log" 2>&1 ||
  { tail -30 "$build/configure.log"; exit 1; }
cmake --build "$build/build" --target opensplat -j "$(nproc)" >"$build/build.log" 2>&1 ||
  { tail -30 "$build/build.log"; exit 1; }
echo "$build/build/opensplat"
