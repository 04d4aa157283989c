#!/usr/bin/env bash
# Installs missing Debian packages, then configures and builds diffipc in build/ (Release, ccache).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install_deps.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DDIFFIPC_TESTS=ON -DDIFFIPC_PYTHON=ON \
  -DDIFFIPC_PYTHON_EXECUTABLE=/usr/bin/python3 > build.log 2>&1 || { cat build.log; exit 1; }
cmake --build build -j "$(nproc)"
