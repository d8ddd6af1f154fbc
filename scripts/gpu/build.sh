#!/usr/bin/env bash
# Builds instainpaint against PyPI's LibTorch 2.x with the CUDA code compiled, and optionally
# runs the tests. One recipe for every machine: `make test-gpu-build` here (no GPU needed: the
# CUDA wheel runs without a driver, GPU tests skip themselves) and scripts/device/ on a lent
# GPU machine (with that machine's own PyTorch: --python python3).
#
# Usage: scripts/gpu/build.sh [--python PY] [--build DIR] [--cuda-arch "8.0;9.0"] [--test]
#   --python PY    a Python whose torch to build against (default: the project-local
#                  environment .venv-gpu, made or brought up to date from requirements.txt)
#   --build DIR    build folder (default build-gpu)
#   --cuda-arch A  CUDA architectures in LibTorch's TORCH_CUDA_ARCH_LIST form (LibTorch's CMake
#                  configuration ignores CMAKE_CUDA_ARCHITECTURES); default "8.0;9.0" (A100, H100/H200)
#   --target T     build only target T (repeatable; default: everything)
#   --cmake-arg A  one more argument to CMake's configuration (repeatable), e.g. -DINSTAINPAINT_PYTHON=ON
#   --test         then run the tests whose code can differ between LibTorch versions and a smoke
#                  run of every command (tests/pypi_build.list), and the Python package's tests
#                  (those that need a GPU skip without one)
#   --all-tests    the same with every test (the page's browser tests excepted)
# Examples:
#   scripts/gpu/build.sh --test                          # what `make test-gpu-build` runs
#   scripts/gpu/build.sh --python ~/venvs/torch/bin/python  # against your own PyTorch
# Environment: JOBS (parallel jobs, default nproc), GPU_VENV (default .venv-gpu).
set -euo pipefail
repo=$(cd "$(dirname "$0")/../.." && pwd)
cd "$repo"

python=""
build=build-gpu
archs=${TORCH_CUDA_ARCH_LIST:-"8.0;9.0"}
run_tests=0
all_tests=0
targets=()
cmake_args=()
while [ $# -gt 0 ]; do
  case "$1" in
    --python) python=$2; shift 2 ;;
    --build) build=$2; shift 2 ;;
    --cuda-arch) archs=$2; shift 2 ;;
    --target) targets+=(--target "$2"); shift 2 ;;
    --cmake-arg) cmake_args+=("$2"); shift 2 ;;
    --test) run_tests=1; shift ;;
    --all-tests) run_tests=1; all_tests=1; shift ;;
    -h|--help) sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0 ;;
    *) echo "gpu/build: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done
jobs=${JOBS:-$(nproc)}
say() { printf 'gpu/build: %s\n' "$*"; }

# ---- 1. the Python whose torch we build against ------------------------------------------
if [ -z "$python" ]; then
  venv=${GPU_VENV:-$repo/.venv-gpu}
  requirements=$repo/scripts/gpu/requirements.txt
  stamp=$venv/.requirements.sha256
  want=$(sha256sum "$requirements" | cut -d' ' -f1)
  if [ ! -x "$venv/bin/python" ]; then
    say "creating $venv"
    python3 -m venv "$venv"
  fi
  if [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
    say "installing scripts/gpu/requirements.txt into $venv (PyPI's torch with CUDA, about 5 GB installed the first time; pip keeps the wheels in its cache)"
    "$repo/scripts/timed.sh" "gpu/build: the PyPI packages" \
      "$venv/bin/pip" install --quiet --disable-pip-version-check --only-binary=:all: -r "$requirements"
    echo "$want" > "$stamp"
  fi
  python=$venv/bin/python
fi
read -r torch_version torch_cuda torch_root < <("$python" -W ignore -c '
import os, torch
print(torch.__version__, torch.version.cuda, os.path.dirname(torch.__file__))')
site=$(dirname "$torch_root")
say "LibTorch $torch_version (CUDA $torch_cuda) from $torch_root"
[ "$torch_cuda" != None ] || { say "this torch has no CUDA: nothing for the CUDA code to build against"; exit 1; }

# ---- 2. the CUDA compiler: NVIDIA's PyPI packages beside torch, else the machine's ---------
cuda_root=""
path_nvcc=$(command -v nvcc || true)
for candidate in "$site/nvidia/cu${torch_cuda%%.*}" "${path_nvcc:+$(dirname "$(dirname "$path_nvcc")")}" /usr/local/cuda; do
  if [ -x "$candidate/bin/nvcc" ]; then cuda_root=$candidate; break; fi
done
[ -n "$cuda_root" ] || { say "no nvcc (pip install 'cuda-toolkit[nvcc,crt,cccl,nvvm,cudart]==$torch_cuda.*' beside torch)"; exit 1; }
nvcc_version=$("$cuda_root/bin/nvcc" --version | sed -n 's/.*release \([0-9.]*\),.*/\1/p')
say "nvcc $nvcc_version from $cuda_root"
if [ "${nvcc_version%%.*}" != "${torch_cuda%%.*}" ]; then
  say "nvcc $nvcc_version and torch's CUDA $torch_cuda differ in the major version: the kernels would need a newer driver than torch"
  exit 1
fi

# PyPI's CUDA packages are laid out differently from a CUDA toolkit: libraries in lib/ (nvcc's
# profile and CMake look in lib64/), only versioned names (libcudart.so.13; CMake looks for
# libcudart.so), cuDNN, NCCL, cuSPARSELt in folders of their own, and no driver library. A
# toolkit-shaped view of links in the build folder gives nvcc, CMake and LibTorch's CMake
# configuration what they expect, plus a stub libcuda.so (soname libcuda.so.1, no driver functions) for
# the link of CUDA::cuda_driver: nothing of ours calls the driver directly and --as-needed keeps
# it out of the binaries, so they start on a machine without a driver.
mkdir -p "$build"
if [ ! -d "$cuda_root/lib64" ]; then
  view=$(cd "$build" && pwd)/cuda-toolkit
  rm -rf "$view"
  mkdir -p "$view/bin" "$view/include" "$view/lib64/stubs"
  ln -s "$cuda_root"/bin/* "$view/bin/"     # nvcc finds its profile and tools beside argv[0]
  ln -s "$cuda_root/nvvm" "$view/"
  ln -s "$cuda_root"/lib/* "$view/lib64/"
  for entry in "$cuda_root"/include/* "$site"/nvidia/*/include/*; do  # nccl.h, cudnn.h, ...
    [ -e "$view/include/$(basename "$entry")" ] || ln -s "$entry" "$view/include/"
  done
  for lib in "$site"/nvidia/*/lib/lib*.so.[0-9]*; do
    name=$(basename "$lib"); name=${name%%.so.*}.so
    [ -e "$view/lib64/$name" ] || ln -s "$lib" "$view/lib64/$name"
  done
  echo 'void ii_libcuda_link_stub(void) {}' |
    cc -x c -shared -fPIC -Wl,-soname,libcuda.so.1 -o "$view/lib64/stubs/libcuda.so" -
  cuda_root=$view
fi

# ---- 3. configure and build ----------------------------------------------------------------
# torch's own folder as the first prefix: its CMake files (share/cmake/Torch) and its libraries
# (lib/) are found before any other LibTorch, Debian's included (cmake/torch_compat.cmake).
say "configuring $build (CUDA architectures $archs)"
if [ -f "$build/CMakeCache.txt" ] && ! grep -qx "Torch_DIR:PATH=$torch_root/share/cmake/Torch" "$build/CMakeCache.txt"; then
  say "$build was configured for another LibTorch: configuring it afresh"
  rm -f "$build/CMakeCache.txt"
fi
cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_PREFIX_PATH="$torch_root" \
  -DCMAKE_CUDA_COMPILER="$cuda_root/bin/nvcc" -DCUDAToolkit_ROOT="$cuda_root" -DCUDA_TOOLKIT_ROOT_DIR="$cuda_root" \
  -DTORCH_CUDA_ARCH_LIST="$archs" -DINSTAINPAINT_REQUIRE_CUDA=ON \
  -DCMAKE_EXE_LINKER_FLAGS="-Wl,--as-needed" -DCMAKE_MODULE_LINKER_FLAGS="-Wl,--as-needed" \
  "${cmake_args[@]}" > "$build/configure.log" 2>&1 || { cat "$build/configure.log"; exit 1; }
grep -E "^-- (CUDA|LibTorch|Default model|Web page)" "$build/configure.log" || true
say "building ($jobs jobs)"
"$repo/scripts/timed.sh" "gpu/build: the build" cmake --build "$build" -j "$jobs" "${targets[@]}"

if readelf -d "$build/instainpaint" | grep -q 'libcuda\.so'; then
  say "$build/instainpaint needs libcuda.so: it would not start without a driver"
  exit 1
fi

# ---- 4. tests --------------------------------------------------------------------------------
if [ "$run_tests" = 1 ]; then
  say "testing ($(command -v nvidia-smi > /dev/null && nvidia-smi -L | head -1 || echo 'no GPU: GPU tests skip'))"
  # One core's share per test (more oversubscribes, and time-budget tests miss their budget).
  # The tests whose code can differ between LibTorch versions, and a smoke run of every command
  # (tests/pypi_build.list): the Debian build runs every test, and everything else compiles to
  # the same behaviour in both builds. --all-tests runs every one here too (the page's browser
  # tests excepted: the page and what it asks of the server are the same in both builds).
  if [ "$all_tests" = 1 ]; then selection=(-LE browser); else selection=(-R "$(python3 "$repo/scripts/gpu/tests.py" --regex)"); fi
  cd "$build" && OMP_NUM_THREADS=${OMP_NUM_THREADS:-$(( $(nproc) / jobs > 1 ? $(nproc) / jobs : 1 ))} \
    "$repo/scripts/timed.sh" "gpu/build: the tests" ctest --output-on-failure --no-tests=error -j "$jobs" "${selection[@]}"
  # The Python package against this torch, imported beside it (only in our own environment:
  # a given --python may have no package index to install the build tools from).
  if [ -n "${venv:-}" ]; then
    say "the Python package: pip install . into $venv, built in $build, against torch $torch_version"
    build_dir=$(pwd)
    cd "$repo"
    "$python" -m pip install --quiet --disable-pip-version-check -r python/requirements-dev.txt
    "$python" -m pip install --quiet --disable-pip-version-check --no-build-isolation --no-deps --config-settings=build-dir="$build_dir" .
    module=$(ls "$build_dir"/python/instainpaint/_core*.so)
    if readelf -d "$module" | grep -q 'libcuda\.so'; then
      say "$module needs libcuda.so: it would not import without a driver"
      exit 1
    fi
    (cd python/tests && INSTAINPAINT_CLI="$build_dir/instainpaint" INSTAINPAINT_BUILD_DIR="$build_dir" \
      "$repo/scripts/timed.sh" "gpu/build: the Python package's tests" "$python" -m pytest -q .)
  fi
fi
