#!/usr/bin/env bash
# The main job: install, build, and simulate the built-in example scene
# (a neo-Hookean cantilever swinging under gravity). Results in output/101_cantilever/.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
./build/cli/diffipc simulate studies/101_cantilever/scene.json -o output/101_cantilever
