#!/usr/bin/env bash
# The generator's realism benchmark (issue #30): for each example set of
# scripts/generator_shape_sets.py, fit the learned and the parametric
# generator to 70 % of the rows and measure their draws against the other
# 30 % (gwml generator fit --holdout 0.3; HOLDOUT changes it), at each
# seed of SEEDS (the training's and the test's). Writes the log to
# OUT/log.txt. The check on blips of a generator trained on real
# data (200 fitted, 200 held out) is, with a set of 400 gengli blips
# (scripts/generator_shape_sets.py DIR --n 400 --seed 2 --gengli):
#     HOLDOUT=0.5 SETS_LIST=gengli scripts/generator_realism.sh DIR OUT
# Usage: [SEEDS="11 12 13"] [SETS_LIST="ringdown ..."] [KINDS="learned parametric"]
#        [HOLDOUT=0.3] scripts/generator_realism.sh SETS_DIR OUT_DIR [GWML]
set -euo pipefail
sets=$1
out=$2
gwml=${3:-target/release/gwml}
mkdir -p "$out"
: > "$out/log.txt"
for seed in ${SEEDS:-11 12 13}; do
    for set in ${SETS_LIST:-ringdown asymmetric chirplet realfit}; do
        for kind in ${KINDS:-learned parametric}; do
            echo "== $set, $kind, seed $seed" | tee -a "$out/log.txt"
            "$gwml" generator fit --family blip --kind "$kind" --examples "$sets/$set.npz" --holdout "${HOLDOUT:-0.3}" \
                --epochs 150 --seed "$seed" --out "$out/$set-$kind-$seed.json" 2>&1 | grep -E "^(trained|fitted|realism)" | tee -a "$out/log.txt"
        done
    done
done
