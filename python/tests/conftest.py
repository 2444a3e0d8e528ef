"""Shared fixtures: the repository's examples and the `gwml` command line,
whose results the package must reproduce."""

import json
import os
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"


def gwml_bin() -> Path:
    """The command-line binary: $GWML_BIN, else a build under target/."""
    if "GWML_BIN" in os.environ:
        return Path(os.environ["GWML_BIN"])
    for profile in ("release", "debug"):
        p = ROOT / "target" / profile / "gwml"
        if p.exists():
            return p
    pytest.fail("no gwml binary: build it with `cargo build` or set GWML_BIN")


def cli(*args: str) -> subprocess.CompletedProcess:
    """Runs `gwml ARGS...` in the repository root."""
    return subprocess.run([str(gwml_bin()), *args], cwd=ROOT, capture_output=True, text=True)


def cli_run(path: Path, scene: str, sets: dict = {}, extra: tuple = ()) -> dict:
    """`gwml run PATH --scene SCENE --grad --format json` with `--set`s."""
    args = ["run", str(path), "--scene", scene, "--grad", "--format", "json", *extra]
    for k, v in sets.items():
        args += ["--set", f"{k}={v!r}" if isinstance(v, float) else f"{k}={v}"]
    r = cli(*args)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout)


def example_scenes():
    """(file, scene) for every scene of every example."""
    import re

    out = []
    for f in sorted(EXAMPLES.glob("*.gw")):
        for name in re.findall(r"^scene (\w+)", f.read_text(), flags=re.M):
            out.append((f, name))
    return out


def close(a: float, b: float, rel: float = 1e-12) -> bool:
    return abs(a - b) <= rel * max(abs(a), abs(b), 1e-300)
