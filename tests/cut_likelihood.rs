//! The cut likelihood (`passes::cutsum`, issue #26 item 6): with the
//! waveform zero above the ISCO, `0.5 (d − h | d − h)` is summed as the
//! masked difference below the cut plus the data's own term, which the
//! scene's prelude computes once per bound input. Checked against the sum
//! computed here from the scene's own waveform and PSD outputs, on data
//! with noise, at points whose ISCO (the cut) moves; the gradient against
//! central differences.

use gwml::{Model, Value};
use gwml_runtime::noise::colored_noise;
use num_complex::Complex64 as C64;

const DF: f64 = 0.125;

#[test]
fn the_split_sum_equals_the_whole_sum_and_its_data_term_is_cached() {
    let model = Model::from_file("examples/taylorf2_tradeoff.gw").unwrap();
    let scene = model.scene(None).unwrap();
    let prelude = scene.pipeline.kernel.prelude.as_ref().expect("the data term is staged");
    assert_eq!(prelude.outputs.len(), 1, "{prelude}");
    // Data: the default signal plus seeded noise of the scene's PSD.
    let out = scene.bind().forward().unwrap();
    let (Value::ComplexArray(signal), Value::RealArray(psd)) = (out.value("h_out").unwrap(), out.value("psd").unwrap()) else {
        panic!("waveform and psd outputs")
    };
    let noise = colored_noise(psd, DF, 4).unwrap();
    let d: Vec<C64> = signal.iter().zip(&noise).map(|(h, n)| h + n).collect();
    let mut run = scene.bind();
    run.input_complex("d", &d).unwrap();
    // Heavier systems cut lower: the split point moves with mc.
    for (mc, q) in [(28.1, 0.8), (20.0, 0.9), (40.0, 0.5), (8.0, 0.3)] {
        run.param("mc", mc).unwrap().param("q", q).unwrap();
        let out = run.value_and_grad().unwrap();
        let Value::ComplexArray(h) = out.value("h_out").unwrap() else { panic!() };
        let whole: f64 = 0.5 * 4.0 * DF * d.iter().zip(h).zip(psd).map(|((d, h), s)| (d - h).norm_sqr() / s).sum::<f64>();
        let loss = out.scalar("loss").unwrap();
        assert!((loss - whole).abs() <= 1e-10 * whole, "mc = {mc}: split {loss}, whole {whole}");
        let nonzero = h.iter().filter(|z| z.norm() > 0.0).count();
        assert!(nonzero < h.len() / 2, "the waveform is cut ({nonzero} bins)");
    }
    assert_eq!(run.prelude_runs(), 1, "the data term once for the data, not per call");
    // The gradient is the split sum's.
    run.param("mc", 28.1).unwrap().param("q", 0.8).unwrap();
    let g = run.value_and_grad().unwrap().grad("loss", "mc").unwrap();
    let at = |mc: f64| {
        let mut r = scene.bind();
        r.input_complex("d", &d).unwrap().param("mc", mc).unwrap().param("q", 0.8).unwrap();
        r.forward().unwrap().scalar("loss").unwrap()
    };
    let fd = (at(28.1 + 1e-6) - at(28.1 - 1e-6)) / 2e-6;
    assert!((g - fd).abs() <= 1e-5 * g.abs().max(1.0), "dloss/dmc {g:e} vs {fd:e}");
}

/// A run keeps each kernel's buffers (forward, gradient) apart; data bound
/// between calls reach both, in whichever order they run after it, and the
/// prelude's cached data term is redone for each.
#[test]
fn a_run_that_alternates_forward_and_gradient_sees_every_binding() {
    let model = Model::from_file("examples/taylorf2_tradeoff.gw").unwrap();
    let scene = model.scene(None).unwrap();
    let out = scene.bind().forward().unwrap();
    let (Value::ComplexArray(signal), Value::RealArray(psd)) = (out.value("h_out").unwrap(), out.value("psd").unwrap()) else {
        panic!("waveform and psd outputs")
    };
    let data = |seed: u64| -> Vec<C64> {
        let noise = colored_noise(psd, DF, seed).unwrap();
        signal.iter().zip(&noise).map(|(h, n)| h + n).collect()
    };
    let fresh =
        |d: &[C64]| scene.bind().input_complex("d", d).unwrap().param("mc", 20.0).unwrap().forward().unwrap().scalar("loss").unwrap();
    let (d1, d2) = (data(5), data(6));
    let (l1, l2) = (fresh(&d1), fresh(&d2));
    assert!((l1 - l2).abs() > 1e-6 * l1.abs(), "two noise draws give two losses ({l1}, {l2})");
    let mut run = scene.bind();
    run.input_complex("d", &d1).unwrap().param("mc", 20.0).unwrap();
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-10 * b.abs();
    assert!(close(run.forward().unwrap().scalar("loss").unwrap(), l1));
    assert!(close(run.value_and_grad().unwrap().scalar("loss").unwrap(), l1));
    // New data: the gradient kernel first, then the forward kernel, whose
    // buffers were filled before the binding.
    run.input_complex("d", &d2).unwrap();
    assert!(close(run.value_and_grad().unwrap().scalar("loss").unwrap(), l2));
    assert!(close(run.forward().unwrap().scalar("loss").unwrap(), l2));
    // And back, the other way round.
    run.input_complex("d", &d1).unwrap();
    assert!(close(run.forward().unwrap().scalar("loss").unwrap(), l1));
    assert!(close(run.value_and_grad().unwrap().scalar("loss").unwrap(), l1));
    assert!(close(run.forward().unwrap().scalar("loss").unwrap(), l1));
}
