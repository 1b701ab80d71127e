#!/usr/bin/env bash
# GPU figures on one lent GPU machine with no install (its image has jax with CUDA), logs in
# $OUT (default: ./gpu_out), in one of three sets:
# - systems (the default): the systems added after the first GPU run (bench_gpu.md): meshes,
#   the cellular Potts model, the lattice domains and the cell simulator;
# - fair: the ratios whose baselines were corrected to morphojax's dtypes (2026-11-26: the
#   mesh port and the lattice oracle in float32, the automata oracle's counts in int32 and
#   its FFT port in float32), logs prefixed fair_;
# - issues: the open issues' GPU figures (logs prefixed issues_): the Euler step against the
#   memory roofline and the solvers beside it (gpu_lattice.py, with the optimised HLO of one
#   short run in issues_hlo.tgz), the Table A.1 rows of 5,000 cells or more, and the README's
#   fit by condition (fit_speed.py).
#
#     bash benchmarks/gpu_systems.sh [systems|fair|issues]
set -u
SET=${1:-systems}
case "$SET" in
  systems) P= ;;
  fair) P=fair_ ;;
  issues) P=issues_ ;;
  *) echo "usage: bash benchmarks/gpu_systems.sh [systems|fair|issues]" >&2; exit 2 ;;
esac
OUT=${OUT:-gpu_out}; mkdir -p "$OUT"; OUT=$(cd "$OUT" && pwd)  # absolute: the runs start in benchmarks/
export PYTHONPATH=$PWD:$PWD/tests:$PWD/benchmarks PYTHONUNBUFFERED=1
{ nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv
  python3 -c "import jax, numpy, scipy; print(jax.__version__, numpy.__version__, scipy.__version__, jax.devices())"
  nproc; } > "$OUT/${P}env.log" 2>&1
cd benchmarks
run() {  # run NAME TIMEOUT SCRIPT ARGS...: the log in $OUT/${P}NAME.log, the exit status in ${P}env.log
  local name=$1 limit=$2; shift 2
  timeout "$limit" python3 "$@" > "$OUT/$P$name.log" 2>&1
  echo "$name: exit $?" >> "$OUT/${P}env.log"
}
if [ "$SET" = systems ]; then
  run mesh 120 bench_mesh.py --repeats 2 --subdivisions 5 6 7
  run potts 100 bench_potts.py --repeats 2
  run domains 110 bench_domains.py --repeats 1 --sizes 250 1000
  run cells 150 bench_cells.py --repeats 1 --only scaling moray
elif [ "$SET" = issues ]; then
  run lattice 110 gpu_lattice.py --sizes 1024 2048 4096 --steps 2000 --unroll 1 8
  XLA_FLAGS=--xla_dump_to=/tmp/hlo timeout 40 python3 gpu_lattice.py --sizes 1024 --steps 8 --unroll 1 \
    --solvers-at 64 > /dev/null 2>&1
  (cd /tmp && find hlo -name '*after_optimizations.txt' | tar -czf "$OUT/${P}hlo.tgz" -T -)
  run cells 190 bench_cells.py --only rows --rows 7.7 7.8 7.18 7.21 --row-repeats 1
  cp results/bench_cells_rows.json "$OUT/${P}bench_cells_rows.json"
  run fit 200 fit_speed.py --repeats 1 --out "$OUT/${P}fit_speed.md"
else
  run mesh 150 bench_mesh.py --repeats 2 --subdivisions 5 7
  run automata 200 bench_automata.py --repeats 7
  run core 150 bench_core.py --repeats 2 --sizes 250 512 1024
fi
