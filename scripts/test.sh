#!/usr/bin/env bash
# Every test: the Rust workspace's, then the Python package's, built into a
# fresh virtualenv (target/python-venv) with its test and JAX extras and
# checked against the command line built by the first step. PyTorch's
# tests run where torch is installed in that virtualenv
# (`target/python-venv/bin/pip install torch`), and are skipped otherwise.
# Last, the MPI tests (`--features mpi`, two ranks under mpirun) where
# OpenMPI is installed; `.ci/run` installs it.
set -euo pipefail
cd "$(dirname "$0")/.."

cargo test --workspace

venv=target/python-venv
rm -rf "$venv"
python3 -m venv "$venv"
# The dev profile: its dependencies are optimised as in `cargo test`.
MATURIN_PEP517_ARGS="--profile dev" "$venv/bin/pip" install --quiet "./python[test,jax]"
GWML_BIN=target/debug/gwml "$venv/bin/python" -m pytest -q python/tests

if command -v mpirun >/dev/null 2>&1; then
    cargo test --features mpi --test mpi
else
    echo "mpirun not found: the MPI tests are skipped (Debian: apt-get install openmpi-bin libopenmpi-dev libclang-dev)"
fi
