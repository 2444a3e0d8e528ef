#!/usr/bin/env bash
# Trains the glitch classifier `gwml scan` ships with and writes it to
# models/glitch-classifier/ (cnn.safetensors; the manifest
# glitch-classifier.json names the model lab/models/glitch/cnn.gw).
#
#     bash scripts/ship_glitch_classifier.sh            # ~10 minutes on 2 cores
#
# Data: `gwml data glitch --centred`: the benchmark population of eight
# classes (lab/src/synth/population.rs: shapes, SNR ranges and noise after
# Gravity Spy's numbers, each class at its own overlapping SNR range,
# residual lines, PSD misestimates and weak transients in the noise) with
# every signal centred as a scan's 1 s trigger window sees it (energy
# centres at 0.4-0.6 s for every class), so position does not give the
# label away. Training set seed 101 (N_TRAIN examples), validation set seed
# 102; the checkpoint with the best validation loss is shipped.
set -euo pipefail
cd "$(dirname "$0")/.."
N_TRAIN=${N_TRAIN:-16000}
EPOCHS=${EPOCHS:-8}
WORK=${WORK:-$(mktemp -d)}
cargo build --release --locked --bin gwml
GWML=target/release/gwml
$GWML data glitch --centred --n "$N_TRAIN" --seed 101 --out "$WORK/train.npz"
$GWML data glitch --centred --n 2000 --seed 102 --out "$WORK/val.npz"
$GWML train lab/models/glitch/cnn.gw --data "$WORK/train.npz" --val "$WORK/val.npz" \
    --epochs "$EPOCHS" --batch 32 --lr 3e-3 --optimizer adam --schedule cosine --clip 10 \
    --checkpoint "$WORK/ckpt" --plot "$WORK/learning_curve.png"
cp "$WORK/ckpt/best.safetensors" models/glitch-classifier/cnn.safetensors
echo "shipped models/glitch-classifier/cnn.safetensors (work files in $WORK)"
