"""`gwml.scan`: the rows `gwml scan` writes, as columns or a DataFrame; the
same rows when a list of files is mapped over a Dask cluster."""

import csv
import math
from pathlib import Path

import numpy as np
import pytest

import gwml

from conftest import cli


@pytest.fixture(scope="module")
def strain_files(tmp_path_factory) -> list:
    """Two 224 s H1 files with a gap between them (two runs)."""
    d = tmp_path_factory.mktemp("strain")
    paths = []
    for k, (gps, seed) in enumerate([(1_000_000_000, 31), (1_000_000_400, 32)]):
        p = d / f"H1-{k}.hdf5"
        r = cli("data", "strain", "--duration", "224", "--gps-start", str(gps), "--seed", str(seed), "--glitch-rate", "10", "--out", str(p))
        assert r.returncode == 0, r.stderr
        paths.append(p)
    return paths


def cli_rows(paths, *extra) -> list:
    out = Path(paths[0]).with_name("cli.csv")
    r = cli("scan", *map(str, paths), "--block", "64", "--out", str(out), *extra)
    assert r.returncode == 0, r.stderr
    with open(out) as f:
        return list(csv.DictReader(f))


def test_scan_returns_the_cli_rows(strain_files):
    rows = cli_rows(strain_files)
    cols = gwml.scan(strain_files, block=64, frame=False)
    assert len(rows) > 5
    assert len(cols["gps_time"]) == len(rows)
    assert isinstance(cols["snr"], np.ndarray) and cols["snr"].dtype == np.float64
    assert cols["tiles"].dtype == np.int64
    classes = [k for k in cols if k.startswith("p_")]
    assert len(classes) >= 6
    for i, row in enumerate(rows):
        # The CSV rounds: 4 decimals for times, 3 for SNR, 2 for frequency and Q.
        assert f"{cols['gps_time'][i]:.4f}" == row["gps_time"]
        assert f"{cols['snr'][i]:.3f}" == row["snr"]
        assert f"{cols['peak_frequency'][i]:.2f}" == row["peak_frequency"]
        assert cols["label"][i] == row["label"] and cols["ifo"][i] == row["ifo"] == "H1"
        assert int(cols["tiles"][i]) == int(row["tiles"])
        for c in classes:
            assert math.isclose(cols[c][i], float(row[c]), abs_tol=6e-5)


def test_scan_without_classifier_and_bad_input(strain_files, tmp_path):
    cols = gwml.scan(strain_files[0], block=64, classify=False, frame=False)
    assert set(cols["label"]) <= {""} and np.isnan(cols["confidence"]).all()
    assert not any(k.startswith("p_") for k in cols)
    missing = tmp_path / "missing.hdf5"
    with pytest.raises(gwml.RunError, match="missing.hdf5"):
        gwml.scan(missing)
    with pytest.raises(gwml.RunError, match="at least 64 s"):
        gwml.scan(strain_files, block=10)
    with pytest.raises(gwml.RunError, match="--min-significance must be positive"):
        gwml.scan(strain_files, min_significance=0.0)
    # A looser excess-power threshold lets noise windows through.
    loose = gwml.scan(strain_files[0], block=64, classify=False, frame=False, min_significance=4.0)
    assert len(loose["gps_time"]) > len(cols["gps_time"])


def test_a_dask_map_over_files_gives_the_rows_of_one_call(strain_files):
    distributed = pytest.importorskip("dask.distributed")
    whole = gwml.scan(strain_files, block=64, frame=False)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        with distributed.Client(cluster) as client:
            futures = client.map(lambda p: gwml.scan(p, block=64, threads=1, frame=False), [str(p) for p in strain_files])
            parts = client.gather(futures)
    for name, column in whole.items():
        joined = np.concatenate([p[name] for p in parts])
        if column.dtype.kind == "f":
            np.testing.assert_array_equal(joined, column, err_msg=name)
        else:
            assert list(joined) == list(column), name
