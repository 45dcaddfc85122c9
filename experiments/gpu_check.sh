#!/usr/bin/env bash
# The GPU check: on a machine with a GPU, in under 5 minutes,
#   1. the fast subset of the test suite (the physics modules' unit tests),
#   2. bench_sph on the full-physics dam break from ~24k to ~1.4M particles,
#   3. the elastic gate at the seed resolution (0.4 s) with its peak against the experiment,
# and writes experiments/results/gpu_check.json (device, test summary, the bench rows,
# the gate's wall time and figures). The same code as on a CPU: nothing is GPU-specific.
#
#   bash experiments/gpu_check.sh                  # python3 with a CUDA jax
#   PY=.venv/bin/python bash experiments/gpu_check.sh
#   GPU_CHECK_ALLOW_CPU=1 GPU_CHECK_DX="0.0029" GPU_CHECK_GATE_T=0.02 bash experiments/gpu_check.sh
#                                                  # a dry run of the plumbing on a CPU
#
# jax-md is the one dependency a CUDA image may lack; it is pure Python: a wheel in .whl/
# (pip download --no-deps jax-md) is installed to /tmp/site when `import jax_md` fails.
set -uo pipefail
cd "$(dirname "$0")/.."
PY=${PY:-python3}
OUT_DIR=experiments/results
TMP=$(mktemp -d)
DX=${GPU_CHECK_DX:-"0.00145 0.00072 0.00036 0.00018"}
GATE_T=${GPU_CHECK_GATE_T:-0.4}
export PYTHONPATH="$PWD${PYTHONPATH:+:$PYTHONPATH}"

if ! $PY -c "import jax_md" 2>/dev/null; then
    if ls .whl/*.whl >/dev/null 2>&1; then
        $PY -m pip install -q --no-index --no-deps --no-compile --target /tmp/site .whl/*.whl
        export PYTHONPATH="$PYTHONPATH:/tmp/site"
    fi
fi
backend=$($PY -c "import jax; print(jax.default_backend())" 2>/dev/null)
if [ "$backend" != "gpu" ] && [ -z "${GPU_CHECK_ALLOW_CPU:-}" ]; then
    echo "gpu_check: jax's backend is '${backend:-none}', not gpu (GPU_CHECK_ALLOW_CPU=1 runs it anyway)" >&2
    exit 2
fi

t0=$(date +%s)
echo "== tests (physics)"
timeout 120 $PY -m pytest -q -p no:cacheprovider tests/physics 2>&1 | tee "$TMP/tests.txt" | tail -3
echo "== bench_sph, dx = $DX"
# shellcheck disable=SC2086
timeout 200 $PY experiments/bench_sph.py --dx $DX --steps 100 --reps 3 --no-old-step \
    --out "$TMP/bench.json" 2>&1 | grep -v Warning
echo "== elastic gate, $GATE_T s"
timeout 150 $PY - "$GATE_T" "$TMP/gate.json" <<'EOF' 2>&1 | grep -v Warning
import json, sys, time
from fpsi_jax import cases
import importlib
from fpsi_jax.run.driver import simulate
t_end, out = float(sys.argv[1]), sys.argv[2]
eg = importlib.import_module("fpsi_jax.cases.elastic_gate")
sc = cases.build("elastic_gate", t_end=t_end)
t0 = time.perf_counter()
res = simulate(sc, progress=False, observe=eg.tip_observer(sc))
wall = time.perf_counter() - t0
m = eg.gate_metrics(*eg.tip_displacement(sc, res))
n = sc.n_particles
rec = {"t_end": t_end, "wall_s": wall, "compile_and_first_chunk_s": res.compile_s,
       "steps": res.n_steps, "dem_substeps": res.physics.dem_substeps, "particles": n,
       "particle_steps_per_s": n * res.n_steps / wall, "rebuilds": res.rebuilds,
       **{k: v for k, v in m.items() if isinstance(v, (int, float))}}
json.dump(rec, open(out, "w"), indent=1)
print(json.dumps(rec))
EOF
echo "== gpu_check.json"
$PY - "$TMP" "$OUT_DIR/gpu_check.json" "$(( $(date +%s) - t0 ))" <<'EOF'
import json, os, sys
import jax
tmp, out, total = sys.argv[1], sys.argv[2], int(sys.argv[3])
def load(name):
    p = os.path.join(tmp, name)
    return json.load(open(p)) if os.path.exists(p) else None
tests = open(os.path.join(tmp, "tests.txt")).read().strip().splitlines()
d = jax.devices()[0]
bench = load("bench.json")
rec = {"device": f"{d.platform}: {d.device_kind}", "jax": jax.__version__,
       "total_wall_s": total, "tests": tests[-1] if tests else "",
       "bench_sph": bench["rows"] if bench else None, "elastic_gate": load("gate.json")}
os.makedirs(os.path.dirname(out), exist_ok=True)
json.dump(rec, open(out, "w"), indent=1)
for r in rec["bench_sph"] or []:
    print(f"N={r['n_particles']:8d} K={r['neighbour_capacity']} "
          f"{r['particle_steps_per_s'] / 1e6:7.2f} M particle-steps/s")
print(out, "written;", total, "s in all")
EOF
rm -rf "$TMP"
