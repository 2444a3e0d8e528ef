#!/usr/bin/env bash
# Dumps every stage's text (`gwml compile --emit ast|ir|adjoint|clif`) for
# every scene of every example and benchmark model, in each precision, into
# OUTDIR: one file per (model, scene, precision, stage). A refactoring that
# must not change behaviour is checked by dumping before and after and
# comparing the two folders:
#
#   scripts/emit_all.sh target/before/gwml /tmp/emit-before
#   scripts/emit_all.sh target/debug/gwml  /tmp/emit-after
#   diff -r /tmp/emit-before /tmp/emit-after && echo identical
#
# A compile that fails (f32 on a scene whose values leave f32's range, say)
# leaves its error message in the dump, to be compared like any output.
set -uo pipefail
if [ $# -ne 2 ]; then
    echo "usage: $0 GWML_BINARY OUTDIR" >&2
    exit 2
fi
gwml=$1
out=$2
cd "$(dirname "$0")/.."
mkdir -p "$out"
# Kernels call library code (FFT plans, tensor ops) through addresses of
# heap objects baked into the IR as 48-bit constants; they change from run
# to run, so they are written as 0xHEAP.
heap_address='s/0x[0-9a-f]{4}_[0-9a-f]{4}_[0-9a-f]{4}\b/0xHEAP/g'
for file in examples/*.gw lab/models/glitch/*.gw benches/*.gw; do
    model=$(echo "${file%.gw}" | tr / _)
    "$gwml" compile "$file" --emit ast >"$out/$model.ast" 2>&1
    for scene in $(sed -n 's/^scene \([A-Za-z_][A-Za-z0-9_]*\).*/\1/p' "$file"); do
        for precision in default f32 mixed; do
            knob=()
            [ "$precision" = default ] || knob=(--precision "$precision")
            for stage in ir adjoint clif; do
                "$gwml" compile "$file" --scene "$scene" "${knob[@]}" --emit "$stage" 2>&1 |
                    sed -E "$heap_address" >"$out/$model.$scene.$precision.$stage"
            done
        done
    done
done
