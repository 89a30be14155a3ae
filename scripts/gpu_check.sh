#!/bin/bash
# The GPU checks of docs/gpu.md in one run on a CUDA machine, each stage under a time limit so
# that a slow one cannot starve the others: the environment, every simulator case and the
# bench lattices on the device against the CPU (pytest -m gpu), then the bench scenes on the
# GPU (numba-cuda's launches, then prepared ones) and on the CPU of the same machine (the
# peer of the ratios in docs/gpu.md). The tests run the launches the environment asks for:
#   BONDEM_CUDA_PREPARED_LAUNCH=1 bash scripts/gpu_check.sh    checks the prepared ones.
#   bash scripts/gpu_check.sh [OUT]     (OUT defaults to $OUT, else ./gpu-check)
# A dry run without a GPU: NUMBA_ENABLE_CUDASIM=1 LATTICE=4 SCENE=300 STEPS=2 WARMUP=1 bash scripts/gpu_check.sh /tmp/x
# Needs numba-cuda and the project's runtime dependencies; runs the checkout's sources.
set -u
out=${1:-${OUT:-gpu-check}}
mkdir -p "$out" /tmp/gpu-check
export PYTHONPATH="$PWD/src${PYTHONPATH:+:$PYTHONPATH}" PYTHONUNBUFFERED=1
export NUMBA_CACHE_DIR=/tmp/gpu-check/numba-cache
threads=$(nproc)
py=${PYTHON:-python3}
lattice=${LATTICE:-47,100} scene=${SCENE:-1e5} steps=${STEPS:-100} warmup=${WARMUP:-200}  # smaller for a dry run

stage() {  # stage NAME SECONDS COMMAND...: run, log to $out/NAME.log, note time and status
    local name=$1 limit=$2; shift 2
    local start=$SECONDS
    timeout "$limit" "$@" > "$out/$name.log" 2>&1
    echo "$name: exit $? after $((SECONDS - start)) s (limit $limit s)" | tee -a "$out/stages.txt"
}

{
    date -u; nvidia-smi; nproc; free -g
    "$py" -c "import numba, numpy; from numba import cuda; print('numba', numba.__version__,
'numpy', numpy.__version__); cuda.detect()"
    "$py" -m pip list 2>/dev/null | grep -i -E "^(numba|numba-cuda|cuda-|numpy|h5py|scipy|click|tqdm)"
} > "$out/env.log" 2>&1

# correctness first: speed of wrong answers is no figure
echo "BONDEM_CUDA_PREPARED_LAUNCH=${BONDEM_CUDA_PREPARED_LAUNCH:-} in the tests" >> "$out/stages.txt"
stage tests 240 "$py" -m pytest tests/test_gpu_sim.py -o addopts="" -q -p no:cacheprovider \
    -m gpu -n 12 -k "not 200" -rA
# each GPU scene with numba-cuda's launches (plain) and with prepared ones (cuda_device.py)
bench=(env NUMBA_NUM_THREADS="$threads" "$py" -m bondem bench)
plain=(env -u BONDEM_CUDA_PREPARED_LAUNCH "${bench[@]}")
prepared=(env BONDEM_CUDA_PREPARED_LAUNCH=1 "${bench[@]}")
j=/tmp/gpu-check
stage bench_lattice_gpu 120 "${plain[@]}" lattice --sizes $lattice --steps $((5 * steps)) --backend gpu --json $j/lg.json
stage bench_lattice_gpu_prepared 120 "${prepared[@]}" lattice --sizes $lattice --steps $((5 * steps)) --backend gpu --json $j/lgp.json
stage bench_lattice_cpu 120 "${bench[@]}" lattice --sizes $lattice --steps $steps --backend cpu --json $j/lc.json
stage bench_impact_gpu 120 "${plain[@]}" impact --sizes $scene --steps $((3 * steps)) --warmup $warmup --backend gpu --json $j/ig.json
stage bench_impact_gpu_prepared 120 "${prepared[@]}" impact --sizes $scene --steps $((3 * steps)) --warmup $warmup --backend gpu --json $j/igp.json
stage bench_impact_cpu 120 "${bench[@]}" impact --sizes $scene --steps $((3 * steps)) --warmup $warmup --backend cpu --json $j/ic.json
stage bench_bed_gpu 120 "${plain[@]}" bed --sizes $scene --steps $((3 * steps)) --backend gpu --json $j/bg.json
stage bench_bed_gpu_prepared 120 "${prepared[@]}" bed --sizes $scene --steps $((3 * steps)) --backend gpu --json $j/bgp.json
stage bench_bed_cpu 120 "${bench[@]}" bed --sizes $scene --steps $steps --backend cpu --json $j/bc.json
stage tests_8e6 100 "$py" -m pytest tests/test_gpu_sim.py -o addopts="" -q -p no:cacheprovider \
    -m gpu -k "200" -rA
"$py" - "$j" "$out/bench.json" <<'EOF'
import json, sys
from pathlib import Path
rows = []
for path in sorted(Path(sys.argv[1]).glob("*.json")):
    data = json.loads(path.read_text())    # run: lg = lattice gpu, lgp = prepared, lc = cpu
    rows += [dict(row, run=path.stem) for row in (data if isinstance(data, list) else [data])]
Path(sys.argv[2]).write_text(json.dumps(rows, indent=1))
EOF
# one folder of logs: at most 8 files come back from a device run
cat "$out"/bench_*.log > "$out/bench.log" 2>/dev/null && rm -f "$out"/bench_*.log
