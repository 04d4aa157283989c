#!/usr/bin/env bash
# Installs missing Debian packages, then configures and builds diffipc in build/ (Release, ccache).
#
#   bash scripts/build.sh          everything: libraries, CLI, Python module, tests, benchmarks, and the CUDA
#                                  kernels wherever nvcc is found (the test command and CI: they keep the
#                                  kernels compiling, and their host-side tests run without a GPU)
#   bash scripts/build.sh --main   what the main job runs (scripts/run_example.sh): the libraries, the CLI
#                                  (with its remesher) and the Python module; the CUDA kernels only where a
#                                  GPU is usable (CMakeLists.txt) or DIFFIPC_CUDA=ON is in the environment
set -euo pipefail
cd "$(dirname "$0")/.."

mode=all
case "${1:-}" in
  "") ;;
  --main) mode=main ;;
  *) echo "build.sh: unknown argument '$1' (use --main, or nothing for everything)" >&2; exit 2 ;;
esac

bash scripts/install_deps.sh
# ccache: paths below the repository root hashed as relative ones, so that another clone (CI's, a second
# checkout) reuses what this machine compiled before.
export CCACHE_BASEDIR="${CCACHE_BASEDIR:-$PWD}"

options=(-DCMAKE_BUILD_TYPE=Release -DDIFFIPC_PYTHON=ON -DDIFFIPC_PYTHON_EXECUTABLE=/usr/bin/python3)
if [ "$mode" = all ]; then
  options+=(-DDIFFIPC_TESTS=ON)
  if command -v nvcc > /dev/null || [ -x /usr/local/cuda/bin/nvcc ] || [ -n "${CUDACXX:-}" ]; then
    options+=(-DDIFFIPC_CUDA=ON)
  fi
elif [ -n "${DIFFIPC_CUDA:-}" ]; then
  options+=(-DDIFFIPC_CUDA="$DIFFIPC_CUDA")
else
  # Decide again (CMakeLists.txt: a usable GPU), whatever a full build cached: turning the kernels off
  # recompiles one file (forward/simulation/device_solver.cpp) and relinks.
  options+=(-UDIFFIPC_CUDA)
fi
cmake -S . -B build "${options[@]}" > build.log 2>&1 || { cat build.log; exit 1; }
grep -E "^-- DIFFIPC_(CUDA|MPI)" build.log || true

if [ "$mode" = all ]; then
  cmake --build build -j "$(nproc)"
else
  cmake --build build -j "$(nproc)" --target diffipc _diffipc
fi
