#!/usr/bin/env bash
# Strong scaling of `gwml scan --mpi` and `gwml train --mpi`, 1 -> N ranks,
# one thread per rank, median wall time of REPS runs each. Needs a release
# build with MPI (`cargo build --release --features mpi`) and mpirun.
#
#     bash benches/cluster/scaling.sh [RANKS=2] [REPS=3] [BLOCK=128]
set -euo pipefail
cd "$(dirname "$0")/../.."
ranks="${1:-2}"
reps="${2:-3}"
block="${3:-128}"
bin=target/release/gwml
work="${TMPDIR:-/tmp}/gwml-scaling"
mkdir -p "$work"
# OpenMPI binds each rank to a core: one rank uses one core, its reading
# thread included, so 1 -> N ranks is 1 -> N cores. `--mca pml ob1` is
# OpenMPI's point-to-point layer for one node (shared memory): the default,
# UCX, spends ~0.22 s of every rank's start probing network devices, a
# fixed cost no cluster with a fabric avoids but this machine has no use for.
mpi=(mpirun --allow-run-as-root --oversubscribe --bind-to core --mca pml ob1)

[ -e "$work/s4096.hdf5" ] || "$bin" data strain --duration 4096 --seed 42 --out "$work/s4096.hdf5" >/dev/null
[ -e "$work/train.npz" ] || "$bin" data bursts --n 4096 --seed 1 --out "$work/train.npz" >/dev/null

median() { sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
timed() { local t0 t1; t0=$(date +%s.%N); "$@" >/dev/null 2>&1; t1=$(date +%s.%N); awk "BEGIN {print $t1 - $t0}"; }

scan_args=(scan "$work/s4096.hdf5" --block "$block" --threads 1 --mpi)
train_args=(train examples/burst_cnn.gw --data "$work/train.npz" --epochs 16 --batch 256 --threads 1 --seed 3 --quiet --mpi)
# Runs alternate between 1 and N ranks, so drifts in the machine's speed
# fall on both.
: >"$work/times.txt"
for _ in $(seq "$reps"); do
    for n in 1 "$ranks"; do
        echo "scan $n $(timed "${mpi[@]}" -n "$n" "$bin" "${scan_args[@]}" --out "$work/t$n.csv")" >>"$work/times.txt"
        echo "train $n $(timed "${mpi[@]}" -n "$n" "$bin" "${train_args[@]}")" >>"$work/times.txt"
    done
done
for what in scan train; do
    one=$(awk -v w="$what" '$1 == w && $2 == 1 {print $3}' "$work/times.txt" | median)
    many=$(awk -v w="$what" -v n="$ranks" '$1 == w && $2 == n {print $3}' "$work/times.txt" | median)
    all=$(awk -v w="$what" '$1 == w {printf "%s/%s ", $2, $3}' "$work/times.txt")
    echo "$what: 1 rank $one s, $ranks ranks $many s: $(awk "BEGIN {printf \"%.2f\", $one / $many}")x (ranks/seconds of every run: $all)"
    [ "$what" != scan ] || echo "scan: 4096 s of strain at $(awk "BEGIN {printf \"%.0f\", 4096 / $one}")x real time on one rank"
done
cmp "$work/t1.csv" "$work/t$ranks.csv" && echo "scan outputs identical"
