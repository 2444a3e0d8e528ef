#!/usr/bin/env bash
# Latency of the REPL: one session evaluates N simple expressions from a
# pipe; prints the median per entry from the REPL's own timing of each
# line (wall clock between echoed prompts is not used: output is buffered).
#
#   cargo build --release && bash benches/peers/repl_latency.sh [N] [FILE.gw]
#
# With FILE.gw the session `:load`s it first (entries then compile beside
# its modules).
set -euo pipefail
cd "$(dirname "$0")/../.."
n="${1:-200}"
load="${2:-}"
bin=target/release/gwml
input=$(mktemp)
{
    if [ -n "$load" ]; then echo ":load $load"; fi
    echo "param x = 0.5"
    for i in $(seq 1 "$n"); do echo "sin(x) * $i.0 + x ^ 2"; done
} > "$input"
start=$(date +%s.%N)
"$bin" repl < "$input" > /dev/null
end=$(date +%s.%N)
# The session start (process, first compile) is included: an upper bound.
echo "$n entries in $(echo "$end - $start" | bc) s: $(echo "($end - $start) * 1000 / ($n + 1)" | bc -l | cut -c1-6) ms per entry (mean, including start-up)"
rm -f "$input"
