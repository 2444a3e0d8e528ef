//! `gwml run --input NAME=FILE.txt` / `NAME=asd:FILE.txt`: noise curves from
//! two-column text files, end to end (`runtime/tests/spectrum.rs` tests the
//! loader itself).

use gwml::spectrum::{Kind, Spectrum};
#[path = "common/cli.rs"]
mod cli;

use cli::{gwml, json};

const SAMPLE: &str = "fixtures/spectra/aligo_zerodet_highpower_asd.txt";

/// A scratch folder for one test, removed when it is dropped.
fn temp_dir() -> tempfile::TempDir {
    tempfile::Builder::new().prefix("gwml-spectrum-cli-").tempdir().unwrap()
}

#[test]
fn snr_with_the_sample_asd_file_matches_the_analytic_psd() {
    let analytic = json(&["run", "examples/snr_aligo.gw", "--grad", "--format", "json"]);
    let input = format!("psd=asd:{SAMPLE}");
    let from_file = json(&["run", "examples/snr_aligo.gw", "--grad", "--format", "json", "--input", &input]);
    let (a, b) = (analytic["outputs"]["rho"].as_f64().unwrap(), from_file["outputs"]["rho"].as_f64().unwrap());
    // The interpolated PSD is within 4.5e-4 of the model everywhere on the
    // grid (runtime/tests/spectrum.rs), so the SNR is too.
    assert!(a > 10.0 && (b / a - 1.0).abs() < 4.5e-4, "SNR from the file {b} vs analytic {a}");
    assert!(b != a, "the file should not give the analytic values bit for bit");
    for p in ["mc", "dist"] {
        let (ga, gb) = (analytic["grads"]["rho"][p].as_f64().unwrap(), from_file["grads"]["rho"][p].as_f64().unwrap());
        assert!((gb / ga - 1.0).abs() < 1e-3, "d rho / d {p}: {gb} vs {ga}");
    }
    // Read as a PSD instead (no squaring), the SNR would be absurd: the prefix matters.
    let wrong = json(&["run", "examples/snr_aligo.gw", "--format", "json", "--input", &format!("psd=psd:{SAMPLE}")]);
    assert!(wrong["outputs"]["rho"].as_f64().unwrap() < 1e-6 * a);
}

#[test]
fn psd_text_files_bind_with_or_without_prefix_and_equal_the_loader() {
    let scratch = temp_dir();
    let dir = scratch.path();
    let src = dir.join("model.gw");
    std::fs::write(
        &src,
        "scene s {
            grid f = frequencies(from: 0 Hz, to: 64 Hz, step: 0.5 Hz)
            input psd: real[f] s
            output p = psd
        }",
    )
    .unwrap();
    let text = "# toy PSD\nfrequency,psd\n4, 1e-40\n16, 1e-44\n32, 4e-45\n";
    let (src, out) = (src.to_str().unwrap(), dir.join("p.npy"));
    let mut results = Vec::new();
    for (file, prefix) in [("toy.txt", ""), ("toy.txt", "psd:"), ("toy.csv", ""), ("toy", "psd:")] {
        let path = dir.join(file);
        std::fs::write(&path, text).unwrap();
        let (ok, _, err) =
            gwml(&["run", src, "--input", &format!("psd={prefix}{}", path.display()), "--output", &format!("p={}", out.display())]);
        assert!(ok, "{file} {prefix}: {err}");
        let p: Vec<f64> = gwml::npy::read(&out).unwrap().values.iter().map(|z| z.re).collect();
        results.push(p);
    }
    let spec = Spectrum::parse(text, "toy", Kind::Psd).unwrap();
    let want: Vec<f64> = (0..129).map(|k| spec.psd_at(0.5 * k as f64)).collect();
    for r in &results {
        assert_eq!(r, &want);
    }
    assert_eq!(want[0], 1e-40); // held below 4 Hz
    assert_eq!(want[32], 1e-44); // 16 Hz, a file point
    assert_eq!(want[128], 4e-45); // held above 32 Hz
}

#[test]
fn bad_spectrum_files_and_inputs_are_errors_with_the_line() {
    let scratch = temp_dir();
    let dir = scratch.path();
    let bad = dir.join("bad.txt");
    std::fs::write(&bad, "# f asd\n10 1e-22\n20 1e-23\n15 1e-23\n").unwrap();
    let (ok, _, err) = gwml(&["run", "examples/snr_aligo.gw", "--input", &format!("psd=asd:{}", bad.display())]);
    assert!(!ok);
    assert!(err.contains(&format!("{}:4: frequencies must increase strictly", bad.display())), "{err}");
    let (ok, _, err) = gwml(&["run", "examples/chirp_fit.gw", "--input", &format!("d={SAMPLE}")]);
    assert!(!ok);
    assert!(err.contains("input `d` is complex"), "{err}");
    let (ok, _, err) = gwml(&["run", "examples/snr_aligo.gw", "--input", "psd=asd:no/such/file.txt"]);
    assert!(!ok);
    assert!(err.contains("cannot read no/such/file.txt"), "{err}");
}
