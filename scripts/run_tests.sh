#!/usr/bin/env bash
# Install, build, and run every test (GoogleTest and pytest through CTest).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
cd build
ctest --output-on-failure -j "$(nproc)"
