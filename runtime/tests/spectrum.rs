//! Noise-curve files (`gwml_runtime::spectrum`): parsing, errors with line
//! numbers, log-log interpolation, and the sample aLIGO file
//! (`fixtures/spectra/aligo_zerodet_highpower_asd.txt`, written from
//! LALSimulation by `scripts/spectrum_fixture.py`) against gwml's analytic
//! `std::psd::psd_aligo_zerodet_highpower`.

use gwml_compiler::ir::Grid;
use gwml_runtime::spectrum::{load, Kind, Spectrum};
use gwml_runtime::{Model, Value};

const SAMPLE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/spectra/aligo_zerodet_highpower_asd.txt");

fn grid(start: f64, step: f64, len: usize) -> Grid {
    Grid { name: "f".into(), start, step, len, unit: "Hz".into(), dims: vec![len] }
}

fn parse(text: &str, kind: Kind) -> Spectrum {
    Spectrum::parse(text, "test.txt", kind).unwrap_or_else(|e| panic!("{e}"))
}

fn parse_err(text: &str) -> String {
    Spectrum::parse(text, "bad.txt", Kind::Psd).expect_err("should be an error").to_string()
}

#[test]
fn file_points_are_exact_and_asd_is_squared() {
    let text = "10 3e-23\n20 2e-23\n40 1.5e-23\n";
    let asd = parse(text, Kind::Asd);
    let psd = parse(text, Kind::Psd);
    assert_eq!(asd.freqs, [10.0, 20.0, 40.0]);
    for (k, v) in [3e-23, 2e-23, 1.5e-23].into_iter().enumerate() {
        assert_eq!(asd.psd[k], v * v);
        assert_eq!(psd.psd[k], v);
        assert_eq!(asd.psd_at(asd.freqs[k]), v * v);
        assert_eq!(psd.psd_at(psd.freqs[k]), v);
    }
    // A grid through the file points gives the file values exactly.
    let on = asd.on_grid(&grid(10.0, 10.0, 4)).unwrap();
    assert_eq!(on[0], 3e-23 * 3e-23);
    assert_eq!(on[1], 2e-23 * 2e-23);
    assert_eq!(on[3], 1.5e-23 * 1.5e-23);
}

#[test]
fn between_points_the_curve_is_a_power_law() {
    // S(f) = 1e-40 (f / 10 Hz)^-4 at 10 and 100 Hz: in between, exactly that law.
    let law = |f: f64| 1e-40 * (f / 10.0).powf(-4.0);
    let s = parse(&format!("10 {:e}\n100 {:e}\n1000 1e-44\n", law(10.0), law(100.0)), Kind::Psd);
    for f in [10.5, 12.0, 31.6227766, 50.0, 99.9] {
        let (got, want) = (s.psd_at(f), law(f));
        assert!((got / want - 1.0).abs() < 1e-13, "f = {f}: {got:e} vs {want:e}");
    }
    // Between 100 and 1000 Hz the slope is log(1e-44 / 1e-44) = 0: constant.
    assert!((s.psd_at(316.0) / 1e-44 - 1.0).abs() < 1e-14);
    // An ASD ∝ f^-1 is a PSD ∝ f^-2.
    let a = parse("10 1e-22\n1000 1e-24\n", Kind::Asd);
    for f in [20.0_f64, 100.0, 500.0] {
        let want = 1e-44 * (f / 10.0).powf(-2.0);
        assert!((a.psd_at(f) / want - 1.0).abs() < 1e-13, "f = {f}: {:e} vs {want:e}", a.psd_at(f));
    }
    // Not linear interpolation: the midpoint of a line in f would be 5.05e-41.
    assert!((s.psd_at(55.0) / law(55.0) - 1.0).abs() < 1e-13);
}

#[test]
fn end_values_are_held_outside_the_file_and_at_zero() {
    let s = parse("10 4\n100 1\n", Kind::Psd);
    let on = s.on_grid(&grid(0.0, 50.0, 5)).unwrap();
    assert_eq!(on[0], 4.0); // f = 0
    assert_eq!(on[2], 1.0); // 100 Hz, the last point
    assert_eq!(on[4], 1.0); // 200 Hz, above the file
    assert_eq!(s.psd_at(5.0), 4.0);
}

#[test]
fn comments_csv_and_headers_parse() {
    let plain = parse("10 4\n100 1\n", Kind::Psd);
    let variants = [
        "# a comment\n% another\n\n10 4   # inline\n\t100\t1 % trailing\n",
        "frequency,psd\n10,4\n100, 1\n",
        "# header comment\nf psd\n10 4\n100 1\n",
        "  10.0e0 , 4.0\n1e2,1\n\n\n",
        "10 4\r\n100 1\r\n",
        "\u{feff}10 4\n100 1\n",
    ];
    for text in variants {
        let s = parse(text, Kind::Psd);
        assert_eq!((&s.freqs, &s.psd), (&plain.freqs, &plain.psd), "{text:?}");
    }
}

#[test]
fn bad_files_are_errors_naming_the_line() {
    let cases = [
        ("10 4\n100 1 7\n", "bad.txt:2: expected two columns"),
        ("10 4\n100,\n", "bad.txt:2: expected two columns"),
        ("10 4\n20 x\n", "bad.txt:2: the PSD value `x` is not a number"),
        ("10 4\nabc 1\n", "bad.txt:2: the frequency `abc` is not a number"),
        ("# c\n10 4\n\n20 3\n20 2\n", "bad.txt:5: frequencies must increase strictly, but 20 Hz follows 20 Hz (line 4)"),
        ("10 4\n20 3\n15 2\n", "bad.txt:3: frequencies must increase strictly, but 15 Hz follows 20 Hz (line 2)"),
        ("10 4\n2e1 3\n20.0 2\n", "bad.txt:3: frequencies must increase strictly, but 20.0 Hz follows 2e1 Hz"),
        ("10 4\n20 0\n", "bad.txt:2: the PSD value 0 at 20 Hz must be positive"),
        ("10 4\n20 -1e-46\n", "bad.txt:2: the PSD value -1e-46 at 20 Hz must be positive"),
        ("10 4\n20 nan\n", "bad.txt:2: the PSD value nan at 20 Hz must be positive and finite"),
        ("10 4\n20 inf\n", "bad.txt:2: the PSD value inf at 20 Hz"),
        ("0 4\n20 1\n", "bad.txt:1: the frequency 0 Hz must be positive"),
        ("10 4\ninf 1\n", "bad.txt:2: the frequency inf Hz must be positive and finite"),
        ("# only comments\n10 4\n", "bad.txt: a spectrum needs at least two points"),
        ("", "bad.txt: a spectrum needs at least two points"),
        ("10 4\nf psd\n", "bad.txt:2: the frequency `f` is not a number"),
    ];
    for (text, want) in cases {
        let e = parse_err(text);
        assert!(e.starts_with(want), "{text:?}: got `{e}`, want `{want}...`");
    }
    // An ASD whose square underflows.
    let e = Spectrum::parse("10 1e-200\n20 1e-200\n", "a.txt", Kind::Asd).unwrap_err().to_string();
    assert!(e.starts_with("a.txt:1: the ASD value 1e-200 at 10 Hz squares to 0e0"), "{e}");
    // A missing file names the path.
    let e = Spectrum::read("/nonexistent/noise.txt", Kind::Psd).unwrap_err().to_string();
    assert!(e.starts_with("cannot read /nonexistent/noise.txt"), "{e}");
}

/// gwml's analytic aLIGO PSD on the W1 grid (20..1024 Hz, df = 1/8 Hz).
fn analytic_psd() -> (Grid, Vec<f64>) {
    let src = "use std::psd::{psd_aligo_zerodet_highpower}
scene analytic {
    grid f = frequencies(from: 20 Hz, to: 1024 Hz, step: 0.125 Hz)
    output psd = psd_aligo_zerodet_highpower(f)
}
";
    let scene = Model::from_source("analytic.gw", src).unwrap_or_else(|e| panic!("{e}")).scene(None).unwrap_or_else(|e| panic!("{e}"));
    let g = scene.ir().grids[0].clone();
    let out = scene.bind().forward().unwrap();
    match out.value("psd").unwrap() {
        Value::RealArray(a) => (g, a.clone()),
        other => panic!("psd is not a real array: {other:?}"),
    }
}

/// The sample file (1 point per Hz, 9..2048 Hz) on the W1 grid agrees with
/// the analytic PSD to 5e-4 relative between file points (log-log
/// interpolation of this curve is worst near 30 Hz, where the measured
/// error is 4.5e-4) and to 5e-14 at the file's integer frequencies (the
/// measured 1.6e-14 is LAL's and gwml's rounding, plus a few ulp from
/// squaring the file's ASD).
#[test]
fn sample_aligo_file_matches_the_analytic_psd() {
    let (g, analytic) = analytic_psd();
    assert_eq!(g.len, 8033);
    let loaded = load(SAMPLE, Kind::Asd, &g).unwrap();
    assert_eq!(loaded.len(), analytic.len());
    let (mut worst, mut worst_f, mut worst_exact) = (0.0_f64, 0.0, 0.0_f64);
    for (k, (l, a)) in loaded.iter().zip(&analytic).enumerate() {
        let f = g.start + k as f64 * g.step;
        let rel = (l / a - 1.0).abs();
        if f.fract() == 0.0 {
            worst_exact = worst_exact.max(rel);
        } else if rel > worst {
            (worst, worst_f) = (rel, f);
        }
    }
    eprintln!("sample file vs analytic PSD: worst {worst:.3e} at {worst_f} Hz, at file points {worst_exact:.3e}");
    assert!(worst < 5e-4, "worst relative error {worst:e} at {worst_f} Hz");
    assert!(worst > 1e-5, "interpolation error {worst:e} is implausibly small: is the file finer than 1 Hz?");
    assert!(worst_exact < 5e-14, "at file points: {worst_exact:e}");
    // The file ends at 2048 Hz and starts at 9 Hz: outside, the ends are held.
    let s = Spectrum::read(SAMPLE, Kind::Asd).unwrap();
    assert_eq!((s.freqs[0], *s.freqs.last().unwrap(), s.freqs.len()), (9.0, 2048.0, 2040));
    assert_eq!(s.psd_at(4000.0), *s.psd.last().unwrap());
    assert_eq!(s.psd_at(0.0), s.psd[0]);
}

#[test]
fn input_spectrum_binds_onto_the_inputs_grid() {
    let src = "scene s {
    grid f = frequencies(from: 0 Hz, to: 100 Hz, step: 10 Hz)
    grid t = times(rate: 4 Hz, duration: 1 s)
    input psd: real[f] s
    input d: complex[f] s
    input x: real[t]
    output total = sum(psd)
}
";
    let scene = Model::from_source("s.gw", src).unwrap().scene(None).unwrap();
    let spec = parse("10 4\n100 1\n", Kind::Psd);
    let mut run = scene.bind();
    run.input_complex("d", &[num_complex::Complex64::new(0.0, 0.0); 11]).unwrap().input_real("x", &[0.0; 4]).unwrap();
    run.input_spectrum("psd", &spec).unwrap();
    let total = run.forward().unwrap().scalar("total").unwrap();
    let want: f64 = (0..11).map(|k| spec.psd_at(10.0 * k as f64)).sum();
    assert!((total - want).abs() <= 1e-15 * want, "{total} vs {want}");
    assert!(run.input_spectrum("d", &spec).err().expect("an error").to_string().contains("is complex"));
    assert!(run.input_spectrum("x", &spec).err().expect("an error").to_string().contains("not Hz"));
    assert!(run.input_spectrum("pds", &spec).err().expect("an error").to_string().contains("did you mean `psd`"));
}
