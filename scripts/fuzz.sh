#!/usr/bin/env bash
# Seeds the fuzz corpora from the repository's own files and runs every
# cargo-fuzz target (fuzz/) for SECONDS each (default 600), two at a time
# on the stable toolchain without sanitizers. Needs `cargo install
# cargo-fuzz`. Crashes land in fuzz/artifacts/TARGET/; replay them as cases
# in tests/fuzz_regressions.rs.
#
#     bash scripts/fuzz.sh [SECONDS] [TARGET...]
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-600}"
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(parse compile_run generated npy npz checkpoint spectrum hdf5)

mkdir -p fuzz/corpus/{parse,compile_run,generated,npy,npz,checkpoint,spectrum,hdf5}
cp -n examples/*.gw stdlib/*.gw benches/*.gw compiler/tests/corpus/*.gw fuzz/corpus/parse/ 2>/dev/null || true
cp -n examples/*.gw benches/*.gw fuzz/corpus/compile_run/ 2>/dev/null || true
cp -n fixtures/strain/*.npy fuzz/corpus/npy/ 2>/dev/null || true
cp -n models/glitch-classifier/*.safetensors fuzz/corpus/checkpoint/ 2>/dev/null || true
cp -n fixtures/spectra/*.txt fuzz/corpus/spectrum/ 2>/dev/null || true
cp -n fixtures/strain/*.hdf5 fuzz/corpus/hdf5/ 2>/dev/null || true
if [ ! -e fuzz/corpus/npz/bursts.npz ]; then
    cargo run -q -- data bursts --n 4 --seed 1 --out fuzz/corpus/npz/bursts.npz >/dev/null
fi

cd fuzz
cargo fuzz build -s none
run() {
    # `generated` reads its bytes as choices: longer inputs from the start
    # give deeper programs than libFuzzer's slowly growing length limit.
    local extra=()
    [ "$1" != generated ] || extra=(-max_len=1024 -len_control=0)
    cargo fuzz run -s none "$1" "corpus/$1" -- -max_total_time="$seconds" "${extra[@]}" -rss_limit_mb=4096 -timeout=20 -print_final_stats=1 >"../target/fuzz-$1.log" 2>&1 \
        && echo "$1: no crash in ${seconds} s ($(grep -o 'stat::number_of_executed_units: [0-9]*' "../target/fuzz-$1.log" | tail -1 | cut -d' ' -f2) runs)" \
        || echo "$1: CRASH, see target/fuzz-$1.log and fuzz/artifacts/$1/"
}
mkdir -p ../target
i=0
for t in "${targets[@]}"; do
    run "$t" &
    i=$((i + 1))
    if [ $((i % 2)) -eq 0 ]; then wait; fi
done
wait
