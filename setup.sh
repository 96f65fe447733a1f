#!/usr/bin/env bash
# One entry point for a fresh Debian 12 machine:
#   ./setup.sh bake   install dependencies, build, bake examples/grids.json (the default scene) to out/default.{exr,png}
#   ./setup.sh test   install dependencies, build, run the whole test suite
set -euo pipefail
cd "$(dirname "$0")"
mode=${1:-bake}

packages=(build-essential cmake ninja-build ccache pkg-config
  libopenvdb-dev libboost-iostreams-dev libopenexr-dev libimath-dev libtinygltf-dev
  libglm-dev libtbb-dev catch2 libembree-dev nlohmann-json3-dev libcli11-dev
  libfmt-dev libstb-dev libdraco-dev libmeshoptimizer-dev gltfpack draco
  zlib1g-dev clang libfuzzer-14-dev slurm-wlm munge
  pybind11-dev python3-dev python3-pytest python3-numpy python3-matplotlib
  python3-openvdb openimageio-tools)

# Blender 3.4 only for its import test (tests/tools/blender): 113 MB to download, 332 MB installed,
# about 40 s to install; a bake does without it.
if [ "$mode" = test ]; then packages+=(blender); fi

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  sudo=""; [ "$(id -u)" -eq 0 ] || sudo="sudo"
  echo "setup: installing ${missing[*]}" >&2
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${missing[@]}" >/dev/null
fi

build=${PENUMBRA_BUILD_DIR:-build}
# The tests CI runs under the sanitizers: every reader, output and command-line error test.
sanitize_spec=${PENUMBRA_SANITIZE_SPEC:-"[stream]~[memory],[io]~[memory],[cli]~[memory],[obj]~[memory],[gltf]~[memory],[ptri]~[memory],[scene]~[memory],[geometry]~[memory],[inputs]~[memory],[paths]~[memory],[output-safety]~[memory],[full-disk]~[memory]"}
# Clones in other directories share the compiler cache: ccache hashes paths relative to here.
export CCACHE_BASEDIR="${CCACHE_BASEDIR:-$PWD}"
cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
# A bake needs only the CLI; the tests need everything (the suite, the Python module, fuzz replays).
if [ "$mode" = bake ]; then
  cmake --build "$build" --parallel "$(nproc)" --target penumbra
else
  cmake --build "$build" --parallel "$(nproc)"
fi

# The Khronos glTF validator, for the vertex-colour tests (they skip when it is missing). Only
# the tests need it, and it is never fatal: offline machines or ones without npm get a notice.
if [ "$mode" = test ]; then
  if command -v npm >/dev/null 2>&1; then
    if [ ! -d "$build/npm/node_modules/gltf-validator" ]; then
      timeout 300 npm install --prefix "$build/npm" gltf-validator --no-audit --no-fund >/dev/null 2>&1 ||
        echo "setup: notice: could not install the npm package gltf-validator (offline?); glTF validation tests will be skipped" >&2
    fi
  else
    echo "setup: notice: npm not found; glTF validation tests will be skipped" >&2
  fi
fi

case "$mode" in
  bake)
    mkdir -p out
    "$build/penumbra" bake examples/grids.json -o out/default.exr --stats out/default-stats.json
    echo "setup: wrote out/default.exr and out/default.png" >&2 ;;
  test)
    (cd "$build" && ctest -j "$(nproc)" --output-on-failure --timeout 1200)
    # The Python module's tests (python/tests), against this build tree, with Debian's python3.
    PENUMBRA_BUILD_DIR="$(cd "$build" && pwd)" /usr/bin/python3 -m pytest -q -p no:cacheprovider python/tests
    # The same tests of readers, outputs and the command line under AddressSanitizer and UBSan,
    # then every parser's fuzzer for a bounded time (docs/reliability.md). PENUMBRA_FUZZ_SECONDS
    # sets the time per harness; PENUMBRA_SANITIZE_TESTS=0 skips both.
    if [ "${PENUMBRA_SANITIZE_TESTS:-1}" != 0 ]; then
      fuzzbuild=${PENUMBRA_FUZZ_BUILD_DIR:-build-fuzz}
      cmake -S . -B "$fuzzbuild" -G Ninja -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_COMPILER=clang++ \
        -DPENUMBRA_FUZZ=ON -DPENUMBRA_SANITIZE=address,undefined -DPENUMBRA_TEST_SPEC="$sanitize_spec" >/dev/null
      cmake --build "$fuzzbuild" --parallel "$(nproc)"
      (cd "$fuzzbuild" && ctest -j "$(nproc)" --output-on-failure --timeout 1200)
      fuzz/run.sh "$fuzzbuild" "${PENUMBRA_FUZZ_SECONDS:-60}"
    fi ;;
  build) ;;
  *) echo "usage: ./setup.sh [bake|test|build]" >&2; exit 2 ;;
esac
