//! `Scene::batch`: many parameter sets of one TaylorF2 scene over a rayon
//! pool give bit-for-bit the results of single runs, in input order, with
//! any thread count; failing items are reported by index.

use gwml_runtime::batch::{Batch, Mode};
use gwml_runtime::{Error, Model, Outputs, Scene, Value};
use num_complex::Complex64 as C64;

const SOURCE: &str = "use std::taylorf2::{tf2_strain}
use std::detector::{inner}

module toy_psd(f: Hz) {
    let y = f / 150 Hz
    1e-47 s * (y ^ (-4.0) + 2.0 + 2.0 * y ^ 2.0)
}

scene tf2_batch {
    grid f = frequencies(from: 20 Hz, to: 256 Hz, step: 0.25 Hz)
    input d: complex[f] s
    param mc: Msun = 10.0 in 1.0..100.0
    param q = 0.8 in 0.02..1.0
    param tc: s = 0.0 in -0.1..0.1
    param phic = 0.0
    let h = tf2_strain(f, mc, q, 0.0, 0.0, 400 Mpc, tc, phic, pn_order: 7)
    output loss = 0.5 * inner(d - h, d - h, toy_psd(f), 0.25 Hz)
    output h_out = h
    grad loss wrt [mc, q, tc, phic]
}
";

const N: usize = 64;
const NAMES: [&str; 3] = ["mc", "q", "tc"];

fn scene() -> Scene {
    Model::from_source("tf2_batch.gw", SOURCE).unwrap_or_else(|e| panic!("{e}")).scene(None).unwrap_or_else(|e| panic!("{e}"))
}

/// The data: the model at mc = 10, q = 0.8, tc = 1 ms, phic = 0.2.
fn data(scene: &Scene) -> Vec<C64> {
    let len = scene.ir().grids[0].len;
    let mut run = scene.bind();
    run.input_complex("d", &vec![C64::new(0.0, 0.0); len]).unwrap();
    run.param("tc", 0.001).unwrap().param("phic", 0.2).unwrap();
    match run.forward().unwrap().value("h_out").unwrap() {
        Value::ComplexArray(h) => h.clone(),
        other => panic!("h_out is not a complex array: {other:?}"),
    }
}

/// N rows of (mc, q, tc), row-major, spread around the data's params.
fn rows() -> Vec<f64> {
    (0..N).flat_map(|i| [9.5 + i as f64 / N as f64, 0.7 + 0.25 * ((i * 7) % N) as f64 / N as f64, 1e-3 * ((i % 5) as f64 - 2.0)]).collect()
}

/// Every number of an output as bits, so equality is bit-for-bit.
fn bits(o: &Outputs) -> Vec<u64> {
    let mut b: Vec<u64> = o.params.iter().map(|p| p.1.to_bits()).collect();
    for (_, v) in &o.values {
        match v {
            Value::Real(x) => b.push(x.to_bits()),
            Value::Complex(z) => b.extend([z.re.to_bits(), z.im.to_bits()]),
            Value::RealArray(a) => b.extend(a.iter().map(|x| x.to_bits())),
            Value::ComplexArray(a) => b.extend(a.iter().flat_map(|z| [z.re.to_bits(), z.im.to_bits()])),
        }
    }
    b.extend(o.grads.iter().map(|g| g.2.to_bits()));
    b
}

/// The same items, one fresh `Run` each, on this thread.
fn single_runs(scene: &Scene, d: &[C64], values: &[f64], mode: Mode) -> Vec<Outputs> {
    values
        .chunks(NAMES.len())
        .map(|row| {
            let mut run = scene.bind();
            run.input_complex("d", d).unwrap().param("phic", 0.3).unwrap();
            for (n, v) in NAMES.iter().zip(row) {
                run.param(n, *v).unwrap();
            }
            match mode {
                Mode::Forward => run.forward().unwrap(),
                Mode::ValueAndGrad => run.value_and_grad().unwrap(),
            }
        })
        .collect()
}

#[test]
fn batch_equals_single_runs_bit_for_bit_in_order() {
    let scene = scene();
    let d = data(&scene);
    let values = rows();
    for mode in [Mode::Forward, Mode::ValueAndGrad] {
        let want = single_runs(&scene, &d, &values, mode);
        let batch = Batch::new(&NAMES, &values).input_complex("d", &d).set("phic", 0.3).mode(mode).threads(Some(2));
        assert_eq!(batch.len(), N);
        let got = scene.batch(&batch).unwrap();
        assert_eq!(got.len(), N);
        for (i, (g, w)) in got.iter().zip(&want).enumerate() {
            // Order: item i ran row i.
            assert_eq!(g.params[0], ("mc".to_string(), values[3 * i]), "{mode:?} item {i}");
            assert_eq!(g.params[1], ("q".to_string(), values[3 * i + 1]), "{mode:?} item {i}");
            assert_eq!(g.params[3], ("phic".to_string(), 0.3), "{mode:?} item {i}");
            assert_eq!(bits(g), bits(w), "{mode:?} item {i} differs from a single run");
            assert_eq!(g.grads.len(), if mode == Mode::ValueAndGrad { 4 } else { 0 });
        }
        // The items really differ from each other (so order is tested).
        let losses: Vec<u64> = got.iter().map(|o| o.scalar("loss").unwrap().to_bits()).collect();
        let mut distinct = losses.clone();
        distinct.sort_unstable();
        distinct.dedup();
        assert_eq!(distinct.len(), N, "{mode:?}: losses should all differ");
    }
}

#[test]
fn one_two_and_global_pool_threads_agree() {
    let scene = scene();
    let d = data(&scene);
    let values = rows();
    let batch = Batch::new(&NAMES, &values).input_complex("d", &d).set("phic", 0.3).mode(Mode::ValueAndGrad);
    let one: Vec<Vec<u64>> = scene.batch(&batch.clone().threads(Some(1))).unwrap().iter().map(bits).collect();
    let two: Vec<Vec<u64>> = scene.batch(&batch.clone().threads(Some(2))).unwrap().iter().map(bits).collect();
    let three: Vec<Vec<u64>> = scene.batch(&batch.clone().threads(Some(3))).unwrap().iter().map(bits).collect();
    let global: Vec<Vec<u64>> = scene.batch(&batch.threads(None)).unwrap().iter().map(bits).collect();
    assert_eq!(one.len(), N);
    assert_eq!(one, two);
    assert_eq!(one, three);
    assert_eq!(one, global);
}

#[test]
fn rows_of_vectors_equal_row_major_values() {
    let scene = scene();
    let d = data(&scene);
    let values = rows();
    let vecs: Vec<Vec<f64>> = values.chunks(3).map(<[f64]>::to_vec).collect();
    let a = scene.batch(&Batch::new(&NAMES, &values).input_complex("d", &d)).unwrap();
    let b = scene.batch(&Batch::from_rows(&NAMES, &vecs).input_complex("d", &d)).unwrap();
    assert_eq!(a.iter().map(bits).collect::<Vec<_>>(), b.iter().map(bits).collect::<Vec<_>>());
}

fn item_error(e: Error) -> (usize, Error) {
    match e {
        Error::Item { index, error } => (index, *error),
        other => panic!("expected an item error, got {other}"),
    }
}

#[test]
fn failing_items_are_reported_by_lowest_index() {
    let scene = scene();
    let d = data(&scene);
    let mut values = rows();
    // Item 37: q out of its bounds 0.02..1; item 50: a NaN chirp mass.
    values[3 * 37 + 1] = 1.5;
    values[3 * 50] = f64::NAN;
    for threads in [Some(1), Some(2), None] {
        for mode in [Mode::Forward, Mode::ValueAndGrad] {
            let batch = Batch::new(&NAMES, &values).input_complex("d", &d).mode(mode).threads(threads);
            let e = scene.batch(&batch).unwrap_err();
            let text = e.to_string();
            assert!(text.starts_with("batch item 37: param `q` = 1.5 is outside its bounds"), "{threads:?} {mode:?}: {text}");
            let (index, inner) = item_error(e);
            assert_eq!(index, 37);
            assert!(matches!(inner, Error::Bind(_)));
        }
    }
    values[3 * 37 + 1] = 0.8;
    let (index, inner) = item_error(scene.batch(&Batch::new(&NAMES, &values).input_complex("d", &d).threads(Some(2))).unwrap_err());
    assert_eq!(index, 50);
    assert!(inner.to_string().contains("not finite"), "{inner}");
}

#[test]
fn bad_batches_are_errors_before_any_item_runs() {
    let scene = scene();
    let d = data(&scene);
    let values = rows();
    let msg = |b: Batch| scene.batch(&b).unwrap_err().to_string();
    // Unknown param, with a suggestion.
    let e = scene.batch(&Batch::new(&["mcc"], &values[..4])).unwrap_err();
    assert!(matches!(&e, Error::UnknownName { kind: "param", suggestion: Some(s), .. } if s == "mc"), "{e}");
    assert!(msg(Batch::new(&NAMES, &values[..7]).input_complex("d", &d)).contains("not a whole number of rows of 3"));
    assert!(msg(Batch::new(&["mc", "mc"], &values[..4])).contains("named twice"));
    assert!(msg(Batch::new(&["mc"], &values[..4]).set("mc", 3.0)).contains("both varied and set"));
    assert!(msg(Batch::new(&[], &[])).contains("at least one param"));
    assert!(msg(Batch::from_rows(&NAMES, &[vec![10.0, 0.8, 0.0], vec![10.0, 0.8]])).contains("batch row 1 has 2 values"));
    assert!(msg(Batch::new(&NAMES, &values).input_complex("d", &d[1..])).contains("needs 945 values"));
    assert!(msg(Batch::new(&NAMES, &values).input_complex("d", &d).threads(Some(0))).contains("at least one thread"));
    // The data input has no default: a batch without it fails on item 0.
    let (index, inner) = item_error(scene.batch(&Batch::new(&NAMES, &values)).unwrap_err());
    assert_eq!(index, 0);
    assert!(inner.to_string().contains("input `d` is not bound"), "{inner}");
    // No rows: no outputs.
    assert!(scene.batch(&Batch::new(&NAMES, &[]).input_complex("d", &d)).unwrap().is_empty());
}
