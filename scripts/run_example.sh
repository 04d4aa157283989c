#!/usr/bin/env bash
# The main job: install, build, then run a built-in optimization end to end (study 401: the
# stiffest cantilever of a given area; forward, adjoint, Ipopt with a true area constraint,
# outputs, figures) and print where the results are. Results in output/401_cantilever_area/.
#
# With an existing build: DIFFIPC_CLI=path/to/diffipc DIFFIPC_PYTHONPATH=dir/holding/diffipc
# skip the install and build steps (both must be given).
set -euo pipefail
cd "$(dirname "$0")/.."
job_start=$(date +%s.%N)

PROBLEM=studies/401_cantilever_area/problem.json
OUT=output/401_cantilever_area
PYTHON=/usr/bin/python3

if [ -n "${DIFFIPC_CLI:-}" ] || [ -n "${DIFFIPC_PYTHONPATH:-}" ]; then
  if [ -z "${DIFFIPC_CLI:-}" ] || [ -z "${DIFFIPC_PYTHONPATH:-}" ]; then
    echo "run_example: set both DIFFIPC_CLI and DIFFIPC_PYTHONPATH, or neither (then it builds)" >&2
    exit 1
  fi
  CLI=$DIFFIPC_CLI
  PYPATH=$DIFFIPC_PYTHONPATH
  BUILT=0
else
  # Only what the main job runs: the libraries, the CLI and the Python module (not the tests, the benchmarks,
  # nor the CUDA kernels where no GPU is usable): scripts/build.sh --main.
  bash scripts/build.sh --main
  CLI=./build/cli/diffipc
  PYPATH=build/python
  BUILT=1
fi

start=$(date +%s.%N)
echo "== diffipc optimize $PROBLEM -o $OUT"
"$CLI" optimize "$PROBLEM" -o "$OUT"
echo "== python3 -m diffipc.plot $OUT --refine 10"
PYTHONPATH=$PYPATH "$PYTHON" -m diffipc.plot "$OUT" --refine 10
end=$(date +%s.%N)

PYTHONPATH=$PYPATH "$PYTHON" - "$OUT" "$start" "$end" "$job_start" "$BUILT" <<'EOF'
import json, os, sys
out, start, end, job_start = sys.argv[1], float(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4])
built = sys.argv[5] == "1"
s = json.load(open(os.path.join(out, "summary.json")))
print(f"""
== results in {os.path.abspath(out)}/
  {s['algorithm']}: {s['stop_reason']} after {s['iterations']} iterations ({s['evaluations']} evaluations); \
J (compliance) {s['initial_J']:.6g} -> {s['final_J']:.6g}; largest relative constraint violation {s['max_violation']:.2g}
  summary.json           stop reason, counts, J, the optimal design variables, timings
  history.csv            J, the area constraint, gradient and step norms per iteration
  convergence.png        J, |J - J_final| / |J_final|, gradient and step norms per iteration
  constraints.png        the area against its bound 0.2 m^2, and its relative violation
  objective_over_time.png  compliance over the load steps, initial and optimal design
  design.png             the initial and the optimal design, coloured by von Mises stress at the final load
  designs.pvd            the rest designs (design_<k>.vtu; design_final.vtu): open in ParaView
  optimal_problem.json   the problem started at the optimum (diffipc gradcheck / optimize it)
  optimize + plot: {end - start:.1f} s wall""" + (f"; install + build before it: {start - job_start:.0f} s; in all: "
                                                 f"{end - job_start:.0f} s" if built else ""))
EOF
