#!/usr/bin/env python3
"""Fixtures for gwml's strain reader and PSD estimator (strain/tests/*.rs).

    python3.11 -m venv /tmp/venv && /tmp/venv/bin/pip install numpy scipy h5py gwpy
    /tmp/venv/bin/python scripts/strain_fixtures.py            # writes fixtures/strain/
    /tmp/venv/bin/python scripts/strain_fixtures.py --check-gwpy FILE.hdf5
    /tmp/venv/bin/python scripts/strain_fixtures.py --decimation   # only the decimation fixture

Writes, into fixtures/strain/ (run with numpy 2, scipy 1.17, h5py 3, gwpy 4):
- gwosc_contiguous.hdf5: H1, GPS 1126259446, 16 s at 512 Hz, contiguous
  storage, NaN over seconds 5-6 with DQmask bit 0 cleared there and bit 5
  cleared in second 10 (the GWOSC layout, as GWOSC's own files hold it:
  fixed-length byte strings, int64 GPSstart/Duration, uint32 DQmask);
- gwosc_chunked_gzip.hdf5: L1, GPS 1187008866, 16 s at 1024 Hz, chunks of
  4096 samples, gzip level 4, every DQ bit set;
- *.strain.npy / *.dq.npy: the exact samples and masks written; and
  gwosc_expected.json: the metadata;
- bad files: gwosc_truncated.hdf5 (the first 3000 bytes of the contiguous
  file), gwosc_missing_xspacing.hdf5, not_hdf5.hdf5;
- qscan_input.npy and qscan_expected.json: gwpy's QTiling (Q 4-64,
  20-400 Hz, mismatch 0.2) over 8 s of white noise with a sine-Gaussian:
  each plane's rows, tile counts and peak (median-normalised energy,
  time, frequency); qimage_expected.json: gwpy's q_transform image of the
  same data (loudest plane, 1000 times x 500 log frequencies), its maximum
  and a coarse grid of its values;
- welch_input.npy and welch_expected.json: scipy.signal.welch of coloured
  noise with a line, 64 s at 256 Hz, Hann window, half overlap, for
  nperseg 256 and 1024, average median and mean, detrend 'constant' and
  False. scipy divides the median by its bias for the number of segments K,
  1 + sum_{i=1}^{(K-1)//2} (1/(2i+1) - 1/(2i)).
- decimation_input.npy and decimation_expected.json (only these, with
  --decimation): scipy.signal.firwin's Kaiser-window low-pass taps (beta
  8) for decimation by 2 and 4 (96 k + 1 taps, cut at 0.98 / k of the
  Nyquist frequency), and 4096 samples of coloured noise with a tone
  filtered by numpy.convolve and kept at every k-th sample (sample j of
  the output at input sample j k: zero phase).
--check-gwpy reads a file with gwpy's GWOSC reader and prints what it found
(exit status 1 if it cannot).
"""
import json
import sys
from pathlib import Path

import numpy as np

OUT = Path(__file__).resolve().parent.parent / "fixtures" / "strain"
DQ_NAMES = [b"DATA", b"CBC_CAT1", b"CBC_CAT2", b"CBC_CAT3", b"BURST_CAT1", b"BURST_CAT2", b"BURST_CAT3"]


def write_gwosc(path, detector, gps, rate, strain, dq, chunks=None, xspacing=True):
    import h5py

    with h5py.File(path, "w") as f:
        kw = dict(chunks=(chunks,), compression="gzip", compression_opts=4) if chunks else {}
        ds = f.create_dataset("strain/Strain", data=strain, dtype="f8", **kw)
        ds.attrs["Xstart"] = np.float64(gps)
        if xspacing:
            ds.attrs["Xspacing"] = np.float64(1.0 / rate)
        ds.attrs["Npoints"] = np.int64(len(strain))
        ds.attrs["Xunits"] = np.bytes_(b"second")
        ds.attrs["Yunits"] = np.bytes_(b"strain")
        f["meta/Detector"] = np.bytes_(detector.encode())
        f["meta/Observatory"] = np.bytes_(detector[0].encode())
        f["meta/GPSstart"] = np.int64(gps)
        f["meta/Duration"] = np.int64(len(strain) // rate)
        f["meta/Type"] = np.bytes_(b"StrainTimeSeries")
        f["meta/UTCstart"] = np.bytes_(b"2015-09-14T09:50:29")
        f["meta/Description"] = np.bytes_(b"Strain data time series from LIGO")
        f["quality/simple/DQmask"] = dq.astype("u4")
        f["quality/simple/DQShortnames"] = np.array(DQ_NAMES)
        f["quality/simple/DQDescriptions"] = np.array([b"Data present"] + [b"category"] * 6)
        f["quality/injections/Injmask"] = np.zeros(len(dq), dtype="u4")
        f["quality/injections/InjShortnames"] = np.array([b"NO_CBC_HW_INJ", b"NO_BURST_HW_INJ"])


def coloured(rng, n, rate):
    """Gaussian noise reddened by a one-pole filter, at strain scale."""
    from scipy.signal import lfilter

    return lfilter([1.0], [1.0, -0.9], rng.standard_normal(n)) * 1e-21


def fixtures():
    import scipy
    import scipy.signal

    OUT.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(20261125)
    expected = {}
    # Contiguous, H1, NaN seconds 5-6.
    rate, seconds, gps = 512, 16, 1126259446
    x = coloured(rng, rate * seconds, rate)
    x[5 * rate : 7 * rate] = np.nan
    dq = np.full(seconds, 127, dtype="u4")
    dq[5:7] = 0
    dq[10] &= ~np.uint32(1 << 5)
    write_gwosc(OUT / "gwosc_contiguous.hdf5", "H1", gps, rate, x, dq)
    np.save(OUT / "gwosc_contiguous.strain.npy", x)
    np.save(OUT / "gwosc_contiguous.dq.npy", dq)
    expected["gwosc_contiguous.hdf5"] = dict(detector="H1", gps_start=gps, sample_rate=rate, duration=seconds, npoints=len(x), nan_seconds=[5, 6])
    write_gwosc(OUT / "gwosc_missing_xspacing.hdf5", "H1", gps, rate, x, dq, xspacing=False)
    (OUT / "gwosc_truncated.hdf5").write_bytes((OUT / "gwosc_contiguous.hdf5").read_bytes()[:3000])
    (OUT / "not_hdf5.hdf5").write_text("gps_time,label\n1126259462.4,Blip\n")
    # Chunked + gzip, L1.
    rate, seconds, gps = 1024, 16, 1187008866
    y = coloured(rng, rate * seconds, rate)
    dq = np.full(seconds, 127, dtype="u4")
    write_gwosc(OUT / "gwosc_chunked_gzip.hdf5", "L1", gps, rate, y, dq, chunks=4096)
    np.save(OUT / "gwosc_chunked_gzip.strain.npy", y)
    np.save(OUT / "gwosc_chunked_gzip.dq.npy", dq)
    expected["gwosc_chunked_gzip.hdf5"] = dict(detector="L1", gps_start=gps, sample_rate=rate, duration=seconds, npoints=len(y), nan_seconds=[])
    for name in expected:
        expected[name]["dq_shortnames"] = [n.decode() for n in DQ_NAMES]
    (OUT / "gwosc_expected.json").write_text(json.dumps(expected, indent=1) + "\n")
    # Welch.
    fs, n = 256.0, 256 * 64
    t = np.arange(n) / fs
    w = coloured(rng, n, fs) / 1e-21 + 0.5 * np.sin(2 * np.pi * 60.0 * t)
    np.save(OUT / "welch_input.npy", w)
    cases = []
    for nperseg in (256, 1024):
        for average in ("median", "mean"):
            for detrend in ("constant", False):
                f, p = scipy.signal.welch(w, fs=fs, window="hann", nperseg=nperseg, noverlap=nperseg // 2,
                                          average=average, detrend=detrend, scaling="density", return_onesided=True)
                cases.append(dict(nperseg=nperseg, average=average, detrend=bool(detrend), df=float(f[1] - f[0]), psd=[float(v) for v in p]))
    (OUT / "welch_expected.json").write_text(json.dumps(dict(scipy=scipy.__version__, fs=fs, cases=cases)) + "\n")
    # Q-transform: white noise with a sine-Gaussian (f0 100 Hz, Q 10, t0
    # 4.2 s), 8 s at 1024 Hz, through gwpy's q_scan (the raw QTiling: no
    # whitening, no interpolation): each plane's frequency rows and peak.
    from gwpy.signal.qtransform import QTiling
    from gwpy.timeseries import TimeSeries

    fs, n = 1024.0, 8 * 1024
    t = np.arange(n) / fs
    tau = 10 / (np.sqrt(2) * np.pi * 100.0)
    h = np.exp(-(((t - 4.2) / tau) ** 2)) * np.cos(2 * np.pi * 100.0 * (t - 4.2))
    q = rng.standard_normal(n) + 20 * h / np.sqrt(np.sum(h * h))
    np.save(OUT / "qscan_input.npy", q)
    ts = TimeSeries(q, sample_rate=fs, t0=0)
    tiling = QTiling(abs(ts.span), fs, qrange=(4, 64), frange=(20, 400), mismatch=0.2)
    planes = []
    for plane in tiling:
        energies = plane.transform(ts.fft().value, epoch=0).energies
        best = max(((float(e.value.max()), float(e.t0.value + e.dt.value * int(e.value.argmax())), float(f))
                    for f, e in zip(plane.frequencies, energies)), key=lambda x: x[0])
        planes.append(dict(q=float(plane.q), frequencies=[float(f) for f in plane.frequencies],
                           ntiles=[int(e.size) for e in energies], peak_energy=best[0], peak_time=best[1], peak_frequency=best[2]))
    (OUT / "qscan_expected.json").write_text(json.dumps(dict(fs=fs, frange=list(tiling.frange), planes=planes)) + "\n")
    # The same data through gwpy's q_transform (the image: loudest plane
    # within 0.5 s of 4.2 s, rows interpolated onto 1000 times over
    # 3.7-4.7 s and 500 log-spaced frequencies); no whitening (white noise).
    img = ts.q_transform(qrange=(4, 64), frange=(20, 400), mismatch=0.2, whiten=False, gps=4.2, search=0.5,
                         outseg=(3.7, 4.7), logf=True)
    v = np.asarray(img.value, dtype=float)
    i, k = np.unravel_index(int(v.argmax()), v.shape)
    times, freqs = img.times.value, img.frequencies.value
    (OUT / "qimage_expected.json").write_text(json.dumps(dict(
        q=float(img.q), shape=list(v.shape), t0=float(times[0]), dt=float(times[1] - times[0]),
        f_lo=float(freqs[0]), f_hi=float(freqs[-1]),
        max_time=float(times[i]), max_frequency=float(freqs[k]), max_value=float(v[i, k]),
        # every 50th column by every 25th row, for a value-by-value check
        coarse=[[float(x) for x in row[::25]] for row in v[::50]],
    )) + "\n")
    for p in sorted(OUT.iterdir()):
        print(f"wrote {p.relative_to(OUT.parent.parent)} ({p.stat().st_size} bytes)")


def decimation_fixture():
    from scipy.signal import firwin

    rng = np.random.default_rng(11)
    n = 4096
    x = coloured(rng, n, 16384.0) + np.cos(2 * np.pi * 300.0 * np.arange(n) / 16384.0 + 0.4)
    np.save(OUT / "decimation_input.npy", x)
    cases = []
    for k in (2, 4):
        taps = firwin(96 * k + 1, 0.98 / k, window=("kaiser", 8.0))
        m = len(taps) // 2
        full = np.convolve(x, taps)
        cases.append(dict(factor=k, taps=[float(h) for h in taps], output=[float(v) for v in full[m:m + n:k]]))
    (OUT / "decimation_expected.json").write_text(json.dumps(dict(cases=cases)) + "\n")
    for name in ("decimation_input.npy", "decimation_expected.json"):
        print(f"wrote fixtures/strain/{name} ({(OUT / name).stat().st_size} bytes)")


def check_gwpy(path):
    from gwpy.timeseries import TimeSeries

    try:
        ts = TimeSeries.read(path, format="hdf5.gwosc")
    except Exception as e:  # noqa: BLE001 - report any reader failure
        print(f"gwpy cannot read {path}: {e}")
        return 1
    print(f"gwpy read {path}: t0 {ts.t0.value}, sample_rate {ts.sample_rate.value} Hz, duration {ts.duration.value} s, "
          f"{int(np.isnan(ts.value).sum())} NaN samples, unit {ts.unit}, name {ts.name}")
    return 0


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "--check-gwpy":
        sys.exit(check_gwpy(sys.argv[2]))
    if sys.argv[1:] == ["--decimation"]:
        decimation_fixture()
        sys.exit(0)
    fixtures()
