#!/usr/bin/env bash
# Every test: the Rust workspace's, then the Python package's, built into a
# fresh virtualenv (target/python-venv) with its test and JAX extras and
# checked against the command line built by the first step. PyTorch's
# tests run where torch is installed in that virtualenv
# (`target/python-venv/bin/pip install torch`), and are skipped otherwise.
set -euo pipefail
cd "$(dirname "$0")/.."

cargo test --workspace

venv=target/python-venv
rm -rf "$venv"
python3 -m venv "$venv"
# The dev profile: its dependencies are optimised as in `cargo test`.
MATURIN_PEP517_ARGS="--profile dev" "$venv/bin/pip" install --quiet "./python[test,jax]"
GWML_BIN=target/debug/gwml "$venv/bin/python" -m pytest -q python/tests
