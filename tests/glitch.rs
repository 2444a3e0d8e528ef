//! `std::glitch`: each family has the morphology its documentation states
//! (peak frequency, duration, a low-frequency head, arches per second, a
//! slower decay, fringe arches), and
//! gradients with respect to every shape parameter match finite differences.

use gwml::{Model, Value};

const RATE: f64 = 4096.0;

/// `h(t)` of `call` on 2 s at 4096 Hz, and its power spectrum |rfft|^2 (0.5 Hz bins).
fn signal(call: &str) -> (Vec<f64>, Vec<f64>) {
    let src = format!(
        "use std::glitch::{{blip, koi_fish, whistle, scratchy, tomte, scattered_light}}\nscene g {{\n  grid t = times(rate: 4096 Hz, duration: 2 s)\n  grid f = spectrum(t)\n  \
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

/// Energy-weighted mean of `|t − t0|` over the samples before and after
/// `t0`: how far a signal reaches each side.
fn reach(h: &[f64], t0: f64) -> (f64, f64) {
    let side = |after: bool| {
        let (mut w, mut wt) = (0.0, 0.0);
        for (j, x) in h.iter().enumerate() {
            let dt = j as f64 / RATE - t0;
            if (dt > 0.0) == after {
                w += x * x;
                wt += x * x * dt.abs();
            }
        }
        wt / w
    };
    (side(false), side(true))
}

#[test]
fn tomte_is_a_low_frequency_burst_with_a_slower_decay() {
    let (h, power) = signal("tomte(t, t0: 1 s, f0: 40 Hz, q: 2.5, asym: 2.0, amp: 1.0)");
    assert!((peak(&power) - 40.0).abs() < 6.0, "peak {}", peak(&power));
    assert!(band_fraction(&power, 15.0, 80.0) > 0.9);
    // The envelope (from two quadratures) decays `asym` times as far as it rises.
    let (h90, _) = signal("tomte(t, t0: 1 s, f0: 40 Hz, q: 2.5, asym: 2.0, amp: 1.0, phi: 1.5707963267948966)");
    let envelope: Vec<f64> = h.iter().zip(&h90).map(|(a, b)| a.hypot(*b)).collect();
    let (before, after) = reach(&envelope, 1.0);
    assert!((after / before - 2.0).abs() < 0.1, "rise {before} s, decay {after} s");
    // At asym 1 it is the blip's sine-Gaussian.
    let (sym, _) = signal("tomte(t, t0: 1 s, f0: 40 Hz, q: 2.5, asym: 1.0, amp: 1.0, phi: 0.3)");
    let (sg, _) = signal("blip(t, t0: 1 s, f0: 40 Hz, q: 2.5, amp: 1.0, phi: 0.3)");
    assert!(sym.iter().zip(&sg).all(|(a, b)| (a - b).abs() < 1e-12));
}

#[test]
fn scattered_light_arches_peak_at_the_fringe_frequency_once_per_half_period() {
    // A surface moving at 1 Hz: arches every 0.5 s, each reaching 40 Hz at
    // its top; no bounces, so one fringe frequency, |40 Hz · cos(2π · 1 Hz · dt)|.
    let (h, power) = signal("scattered_light(t, t0: 1 s, f_fringe: 40 Hz, f_motion: 1 Hz, bounce: 0.0, duration: 4 s, amp: 1.0)");
    assert!(band_fraction(&power, 0.0, 41.0) > 0.97, "{}", band_fraction(&power, 0.0, 41.0));
    // Zero crossings 0.1 s either side of an arch's top: the instantaneous
    // frequency there is 40 cos(0.2 π) = 32.4 Hz, so ~6.5 crossings per 0.1 s;
    // at the arch's foot (dt = 0.25 s) it falls to zero.
    let crossings = |from: f64, to: f64| {
        let (a, b) = ((from * RATE) as usize, (to * RATE) as usize);
        h[a..b].windows(2).filter(|w| w[0].signum() != w[1].signum()).count()
    };
    let top = crossings(0.95, 1.05);
    assert!((7..=9).contains(&top), "{top} zero crossings in 0.1 s at the top (40 Hz: 8)");
    assert!(crossings(1.2, 1.3) <= 3, "{} crossings near the foot", crossings(1.2, 1.3));
    // The next arch tops 0.5 s later.
    assert!((7..=9).contains(&crossings(1.45, 1.55)));
    // A bounce adds the second harmonic's arch.
    let (_, bounced) = signal("scattered_light(t, t0: 1 s, f_fringe: 40 Hz, f_motion: 1 Hz, bounce: 0.5, duration: 4 s, amp: 1.0)");
    assert!(band_fraction(&bounced, 42.0, 81.0) > 0.1 && band_fraction(&power, 42.0, 81.0) < 0.01);
}

#[test]
fn every_shape_parameter_has_a_correct_gradient() {
    let src = "use std::glitch::{blip, koi_fish, whistle, scratchy, tomte, scattered_light}\nscene g {\n  \
               grid t = times(rate: 4096 Hz, duration: 1 s)\n  \
               input n: real[t] = sin(200.0 * t / 1 s) + sin(880.0 * t / 1 s) + cos(5000.0 * t / 1 s) + sin(230.0 * t / 1 s)\n  \
               param f0: Hz = 140.0\n  param q = 3.5\n  param t0: s = 0.5\n  param fh: Hz = 32.0\n  param lead: s = 0.03\n  \
               param fmin: Hz = 650.0\n  param fmax: Hz = 950.0\n  param half: s = 0.15\n  param rate: Hz = 18.0\n  param dur: s = 0.6\n  \
               param qh = 4.0\n  param tail = 2.0\n  param drift = 0.1\n  param asym = 1.7\n  \
               param ff: Hz = 38.0\n  param fm: Hz = 0.8\n  param bounce = 0.3\n  param wig: Hz = 120.0\n  param wob = 0.15\n  \
               output loss = sum(n * (blip(t, t0, f0, q, 1.0) + blip(t, t0, 1.3 * f0, q, 1.0, asym: 0.6 * asym, drift: -drift) \
               + koi_fish(t, t0, f0, q, 1.0, f_head: fh, lead: lead, q_head: qh, tail: tail, drift: drift) \
               + whistle(t, t0, fmin, fmax, half, 1.0, wiggle: wig) + scratchy(t, t0, f0, rate, dur, 1.0, wobble: wob) \
               + tomte(t, t0, 0.3 * f0, q, asym, 1.0) \
               + scattered_light(t, t0, ff, fm, bounce, dur, 1.0)))\n  \
               grad loss wrt [f0, q, t0, fh, lead, fmin, fmax, half, rate, dur, qh, tail, drift, asym, ff, fm, bounce, wig, wob]\n}\n";
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
        ("qh", 4.0),
        ("tail", 2.0),
        ("drift", 0.1),
        ("asym", 1.7),
        ("ff", 38.0),
        ("fm", 0.8),
        ("bounce", 0.3),
        ("wig", 120.0),
        ("wob", 0.15),
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
