//! `std::glitch`: each family has the morphology its documentation states
//! (peak frequency, duration, a low-frequency head, arches per second), and
//! gradients with respect to every shape parameter match finite differences.

use gwml::{Model, Value};

const RATE: f64 = 4096.0;

/// `h(t)` of `call` on 2 s at 4096 Hz, and its power spectrum |rfft|^2 (0.5 Hz bins).
fn signal(call: &str) -> (Vec<f64>, Vec<f64>) {
    let src = format!(
        "use std::glitch::{{blip, koi_fish, whistle, scratchy}}\nscene g {{\n  grid t = times(rate: 4096 Hz, duration: 2 s)\n  grid f = spectrum(t)\n  \
         output h = {call}\n  output power = abs2(rfft(h, f)) / 1 s^2\n}}\n"
    );
    let model = Model::from_source("glitch.gw", &src).unwrap_or_else(|e| panic!("{e}"));
    let out = model.scene(None).unwrap().bind().forward().unwrap();
    let array = |name: &str| match out.value(name).unwrap() {
        Value::RealArray(a) => a.clone(),
        v => panic!("{name}: {v:?}"),
    };
    (array("h"), array("power"))
}

/// Frequency (Hz) of the largest bin.
fn peak(power: &[f64]) -> f64 {
    let k = (0..power.len()).fold(0, |b, i| if power[i] > power[b] { i } else { b });
    k as f64 * 0.5
}

/// Fraction of the power between `lo` and `hi` Hz.
fn band_fraction(power: &[f64], lo: f64, hi: f64) -> f64 {
    let total: f64 = power.iter().sum();
    power.iter().enumerate().filter(|(k, _)| (lo..=hi).contains(&(*k as f64 * 0.5))).map(|(_, p)| p).sum::<f64>() / total
}

/// Time (s) between 5 % and 95 % of the cumulative energy.
fn duration(h: &[f64]) -> f64 {
    let total: f64 = h.iter().map(|x| x * x).sum();
    let mut acc = 0.0;
    let (mut start, mut end) = (None, 0);
    for (j, x) in h.iter().enumerate() {
        acc += x * x;
        if start.is_none() && acc >= 0.05 * total {
            start = Some(j);
        }
        if acc <= 0.95 * total {
            end = j;
        }
    }
    (end - start.unwrap_or(0)) as f64 / RATE
}

#[test]
fn blip_is_short_and_broadband_at_f0() {
    let (h, power) = signal("blip(t, t0: 1 s, f0: 150 Hz, q: 3.0, amp: 1.0)");
    assert!((peak(&power) - 150.0).abs() < 15.0, "peak {}", peak(&power));
    assert!(duration(&h) < 0.012, "90 % of the energy within {} s", duration(&h));
    // Broadband: the half-power band is tens of Hz wide.
    assert!(band_fraction(&power, 100.0, 200.0) > 0.8 && band_fraction(&power, 140.0, 160.0) < 0.5);
}

#[test]
fn koi_fish_has_a_low_frequency_head() {
    let (_, power) = signal("koi_fish(t, t0: 1 s, f0: 130 Hz, q: 3.0, amp: 1.0, f_head: 30 Hz)");
    assert!((peak(&power) - 130.0).abs() < 15.0, "peak {}", peak(&power));
    let head = band_fraction(&power, 15.0, 45.0);
    assert!(head > 0.05 && head < 0.4, "head carries {head} of the power");
}

#[test]
fn whistle_sweeps_between_its_frequencies() {
    let (h, power) = signal("whistle(t, t0: 1 s, f_min: 600 Hz, f_max: 1000 Hz, half: 0.2 s, amp: 1.0)");
    assert!(band_fraction(&power, 590.0, 1100.0) > 0.95, "{}", band_fraction(&power, 590.0, 1100.0));
    assert!((600.0..700.0).contains(&peak(&power)), "the arc lingers near f_min: peak {}", peak(&power));
    let d = duration(&h);
    assert!((0.2..0.5).contains(&d), "duration {d} s");
}

#[test]
fn scratchy_is_a_long_train_of_arches() {
    let (h, power) = signal("scratchy(t, t0: 1 s, f0: 150 Hz, rate: 20 Hz, duration: 1 s, amp: 1.0)");
    assert!((peak(&power) - 150.0).abs() < 25.0, "peak {}", peak(&power));
    let d = duration(&h);
    assert!((0.5..1.2).contains(&d), "duration {d} s");
    // The energy envelope h^2 repeats 20 times a second: its spectrum between
    // 5 and 60 Hz peaks at 20 Hz (a direct DFT).
    let e: Vec<f64> = h.iter().map(|x| x * x).collect();
    let amp = |f: f64| {
        let (mut re, mut im) = (0.0, 0.0);
        for (j, v) in e.iter().enumerate() {
            let a = std::f64::consts::TAU * f * j as f64 / RATE;
            re += v * a.cos();
            im -= v * a.sin();
        }
        re.hypot(im)
    };
    let best = (5..=60).map(|f| f as f64).fold(5.0, |b, f| if amp(f) > amp(b) { f } else { b });
    assert_eq!(best, 20.0);
}

#[test]
fn every_shape_parameter_has_a_correct_gradient() {
    let src = "use std::glitch::{blip, koi_fish, whistle, scratchy}\nscene g {\n  grid t = times(rate: 4096 Hz, duration: 1 s)\n  \
               input n: real[t] = sin(200.0 * t / 1 s) + sin(880.0 * t / 1 s) + cos(5000.0 * t / 1 s)\n  \
               param f0: Hz = 140.0\n  param q = 3.5\n  param t0: s = 0.5\n  param fh: Hz = 32.0\n  param lead: s = 0.03\n  \
               param fmin: Hz = 650.0\n  param fmax: Hz = 950.0\n  param half: s = 0.15\n  param rate: Hz = 18.0\n  param dur: s = 0.6\n  \
               output loss = sum(n * (blip(t, t0, f0, q, 1.0) + koi_fish(t, t0, f0, q, 1.0, f_head: fh, lead: lead) \
               + whistle(t, t0, fmin, fmax, half, 1.0) + scratchy(t, t0, f0, rate, dur, 1.0)))\n  \
               grad loss wrt [f0, q, t0, fh, lead, fmin, fmax, half, rate, dur]\n}\n";
    let model = Model::from_source("grad.gw", src).unwrap_or_else(|e| panic!("{e}"));
    let scene = model.scene(None).unwrap();
    let mut run = scene.bind();
    let out = run.value_and_grad().unwrap();
    for (name, x0) in [
        ("f0", 140.0),
        ("q", 3.5),
        ("t0", 0.5),
        ("fh", 32.0),
        ("lead", 0.03),
        ("fmin", 650.0),
        ("fmax", 950.0),
        ("half", 0.15),
        ("rate", 18.0),
        ("dur", 0.6),
    ] {
        let g = out.grad("loss", name).unwrap();
        let h = 1e-7 * f64::max(x0, 1e-3);
        let mut at = |x: f64| {
            run.param(name, x).unwrap();
            run.forward().unwrap().scalar("loss").unwrap()
        };
        let fd = (at(x0 + h) - at(x0 - h)) / (2.0 * h);
        run.param(name, x0).unwrap();
        assert!(g.abs() > 1e-3, "dloss/d{name} = {g} is too small to check");
        assert!((g - fd).abs() <= 1e-5 * g.abs().max(fd.abs()), "dloss/d{name}: {g} vs {fd}");
    }
}
