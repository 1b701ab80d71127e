#!/usr/bin/env bash
# The GPU ratios whose baselines were corrected to compute in morphojax's dtypes (2026-11-26:
# the mesh port and the lattice oracle in float32, the automata oracle's counts in int32 and
# its FFT port in float32), on one lent GPU machine with no install. Logs go to $OUT.
#
#     OUT=gpu_out bash benchmarks/gpu_fair_baselines.sh
set -u
OUT=${OUT:-gpu_out}; mkdir -p "$OUT"; OUT=$(cd "$OUT" && pwd)  # absolute: the runs start in benchmarks/
export PYTHONPATH=$PWD:$PWD/tests:$PWD/benchmarks PYTHONUNBUFFERED=1
{ nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv; python3 -c "import jax, numpy, scipy; print(jax.__version__, numpy.__version__, scipy.__version__, jax.devices())"; nproc; } > $OUT/fair_env.log 2>&1
cd benchmarks
timeout 150 python3 bench_mesh.py --repeats 2 --subdivisions 5 7 > $OUT/fair_mesh.log 2>&1; echo "mesh: exit $?" >> $OUT/fair_env.log
timeout 200 python3 bench_automata.py --repeats 7 > $OUT/fair_automata.log 2>&1; echo "automata: exit $?" >> $OUT/fair_env.log
timeout 150 python3 bench_core.py --repeats 2 --sizes 250 512 1024 > $OUT/fair_core.log 2>&1; echo "core: exit $?" >> $OUT/fair_env.log
