#!/usr/bin/env bash
# Trains the glitch classifier `gwml scan` ships with and writes it to
# models/glitch-classifier/ (template_net.safetensors; the manifest
# glitch-classifier.json names the model lab/models/glitch/template_net.gw,
# the glitch experiment's differentiable template bank + head, its best
# method: results/glitch/README.md).
#
#     bash scripts/ship_glitch_classifier.sh            # ~20-30 minutes on 2 cores (105-181 s an epoch)
#
# Data: `gwml data glitch --centred`: the benchmark population of eight
# classes (lab/src/synth/population.rs: shapes, SNR ranges and noise after
# Gravity Spy's numbers, each class at its own overlapping SNR range,
# half the Blips, Koi Fish and Tomtes shaped after real O3 glitches' fits
# (lab/src/synth/real_fits.rs), residual lines, PSD misestimates and weak
# transients in the noise) with every signal centred as a scan's 1 s
# trigger window sees it (energy centres at 0.4-0.6 s for every class), so
# position does not give the label away. Training set seed 101 (N_TRAIN
# examples), validation set seed 102; the checkpoint with the best
# validation loss is shipped. MODEL=cnn trains the CNN instead (the
# manifest must then name lab/models/glitch/cnn.gw and cnn.safetensors).
#
# Two thirds of the Blips (GENERATOR_SHARE) take their shape from the learned
# generator GENERATOR (models/generators/blip-gengli.json; GENERATOR= for
# none), fitted to 500 blips of gengli's generative networks trained on
# real H1 and L1 Blips (Lopez et al. 2022), which reach down to 50-80 Hz
# with broadband tails, where neither the formula Blips nor O3's real-fit
# Blips go. It was made by
#     python3 scripts/generator_shape_sets.py DIR --n 500 --seed 1 --gengli
#     gwml generator fit --family blip --examples DIR/gengli.npz --seed 1 \
#         --out models/generators/blip-gengli.json
# (gengli and torch in a virtualenv outside the repository).
#
# The trained weights give posteriors for the population's uniform class
# shares; a scan classifies only windows where a trigger crossed its
# threshold, and few of those are noise: NONE_PRIOR (0.04: 19 of the 440
# triggers of the design file, `gwml data strain --duration 4096 --seed 42`,
# lay more than 1 s from every injection) is folded into the output bias by
# scripts/fold_prior.py (Bayes' rule for a new prior; the other classes share
# the rest equally). NONE_PRIOR= ships the trained weights as they are.
set -euo pipefail
cd "$(dirname "$0")/.."
MODEL=${MODEL:-template_net}
N_TRAIN=${N_TRAIN:-40000}
EPOCHS=${EPOCHS:-10}
GENERATOR=${GENERATOR-models/generators/blip-gengli.json}
GENERATOR_SHARE=${GENERATOR_SHARE:-0.67}
NONE_PRIOR=${NONE_PRIOR-0.04}
case "$MODEL" in cnn) BIAS=cnn.b5 ;; *) BIAS=head.bo ;; esac
WORK=${WORK:-$(mktemp -d)}
mkdir -p "$WORK"
cargo build --release --locked --bin gwml
GWML=target/release/gwml
generated=()
if [ -n "$GENERATOR" ]; then
    generated=(--generator "$GENERATOR" --generator-share "$GENERATOR_SHARE")
fi
$GWML data glitch --centred --n "$N_TRAIN" --seed 101 "${generated[@]}" --out "$WORK/train.npz"
$GWML data glitch --centred --n 2000 --seed 102 "${generated[@]}" --out "$WORK/val.npz"
$GWML train "lab/models/glitch/$MODEL.gw" --data "$WORK/train.npz" --val "$WORK/val.npz" \
    --epochs "$EPOCHS" --batch 32 --lr 3e-3 --optimizer adam --schedule cosine --clip 10 \
    --checkpoint "$WORK/ckpt" --plot "$WORK/learning_curve.png"
if [ -n "$NONE_PRIOR" ]; then
    python3 scripts/fold_prior.py "$WORK/ckpt/best.safetensors" "models/glitch-classifier/$MODEL.safetensors" \
        --manifest models/glitch-classifier/glitch-classifier.json --bias "$BIAS" --prior "None=$NONE_PRIOR"
else
    cp "$WORK/ckpt/best.safetensors" "models/glitch-classifier/$MODEL.safetensors"
fi
echo "shipped models/glitch-classifier/$MODEL.safetensors (work files in $WORK)"
