#!/usr/bin/env bash
# The GPU figures of the systems added after the first GPU run (bench_gpu.md): meshes, the
# cellular Potts model, the lattice domains and the cell simulator, on one lent GPU machine
# with no install (its image has jax with CUDA). Logs go to $OUT (default: ./gpu_out).
#
#     bash benchmarks/gpu_systems.sh
set -u
OUT=${OUT:-gpu_out}; mkdir -p "$OUT"; OUT=$(cd "$OUT" && pwd)  # absolute: the runs start in benchmarks/
export PYTHONPATH=$PWD:$PWD/tests:$PWD/benchmarks PYTHONUNBUFFERED=1
{ nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv
  python3 -c "import jax; print(jax.__version__, jax.devices())"; nproc; } > "$OUT/env.log" 2>&1
cd benchmarks
run() {  # run NAME TIMEOUT SCRIPT ARGS...: the log in $OUT/NAME.log, the exit status in env.log
  local name=$1 limit=$2; shift 2
  timeout "$limit" python3 "$@" > "$OUT/$name.log" 2>&1
  echo "$name: exit $?" >> "$OUT/env.log"
}
run mesh 120 bench_mesh.py --repeats 2 --subdivisions 5 6 7
run potts 100 bench_potts.py --repeats 2
run domains 110 bench_domains.py --repeats 1 --sizes 250 1000
run cells 150 bench_cells.py --repeats 1 --only scaling moray
