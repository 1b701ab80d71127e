#!/usr/bin/env bash
# The GPU figures of the systems added after the first GPU run (bench_gpu.md): meshes, the
# cellular Potts model, the lattice domains and the cell simulator, on one lent GPU machine
# with no install (its image has jax with CUDA). Logs go to $OUT (default: ./gpu_out).
#
#     bash benchmarks/gpu_systems.sh
set -u
OUT=${OUT:-gpu_out}; mkdir -p "$OUT"
export PYTHONPATH=$PWD:$PWD/tests:$PWD/benchmarks PYTHONUNBUFFERED=1
{ nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv
  python3 -c "import jax; print(jax.__version__, jax.devices())"; nproc; } > "$OUT/env.log" 2>&1
cd benchmarks
timeout 120 python3 bench_mesh.py --repeats 2 --subdivisions 5 6 7 > "$OUT/mesh.log" 2>&1
timeout 100 python3 bench_potts.py --repeats 2 > "$OUT/potts.log" 2>&1
timeout 110 python3 bench_domains.py --repeats 1 --sizes 250 1000 > "$OUT/domains.log" 2>&1
timeout 150 python3 bench_cells.py --repeats 1 --only scaling moray > "$OUT/cells.log" 2>&1
echo "exit codes: done" >> "$OUT/env.log"
