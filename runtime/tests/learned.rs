//! Learned components: every layer, activation and loss of `std::nn`, its
//! gradient with respect to weights (and physics params) from the JIT's
//! fused value-and-gradient kernel against central finite differences of
//! the JIT's forward kernel, in f64; the JIT against the reference
//! interpreter; and the extremes (logits of ±1e4, pooling ties).

mod common;

use common::{check_against_interpreter, check_weight_gradients, pseudo_random, scalar};
use gwml_runtime::{Model, Value};

/// A scene over `n` inputs `x` running learned component `net`, with loss `out`.
fn wrap(body: &str, n: usize) -> String {
    format!(
        "use std::nn::{{relu, leaky_relu, sigmoid, softplus, gelu, log_softmax, softmax, cross_entropy, mse, layer_norm, kl_normal, gaussian_nll}}\n\
         learned net(x) {{\n{body}\n}}\n\
         scene s {{\n  grid g = index({n})\n  input x: real[g] = 0.0\n  output out = net(x)\n  grad out wrt net\n}}\n"
    )
}

#[test]
fn activations_and_losses_have_correct_weight_gradients() {
    let n = 7;
    let x = pseudo_random(n, 1);
    for formula in [
        "sum(relu(w) * x)",
        "sum(leaky_relu(w, 0.1) * x)",
        "sum(sigmoid(3.0 * w) * x)",
        "sum(softplus(4.0 * w) * x)",
        "sum(gelu(2.0 * w) * x)",
        "sum(tanh(w) * x) + sum(sin(3.0 * w) * x)",
        "sum(log_softmax(3.0 * w) * x)",
        "sum(softmax(w) * x)",
        "cross_entropy(w, softmax(x))",
        "mse(w, x)",
        "sum(layer_norm(w) * x)",
        "sum(dropout(w * w, 0.3) * x)",
        "kl_normal(w, 0.7 * x)",
        "kl_normal(x, w)",
        "gaussian_nll(x, w, 0.5 * w)",
    ] {
        let src = wrap(&format!("    weight w: [{n}] = normal(std: 1.0, seed: 5)\n    {formula}"), n);
        check_weight_gradients(&src, &[("x", x.clone())], "out");
    }
}

#[test]
fn dense_layers_have_correct_gradients() {
    let src = wrap(
        "    weight w1: [5, 6] = glorot(seed: 1)\n    weight b1: [5] = normal(std: 0.3, seed: 2)\n    weight w2: [3, 5] = he(seed: 3)\n    \
         let h = tanh(dense(x, w1, b1))\n    sum(dense(h, w2) * dense(h, w2))",
        6,
    );
    let data = [("x", pseudo_random(6, 4))];
    check_weight_gradients(&src, &data, "out");
    check_against_interpreter(&src, &data);
}

#[test]
fn convolutions_with_stride_padding_and_dilation_have_correct_gradients() {
    for (stride, padding, dilation, kernel) in [(1, 0, 1, 3), (2, 1, 1, 4), (3, 2, 2, 3), (1, 3, 3, 2)] {
        let src = format!(
            "learned net(x) {{\n    weight k1: [3, 1, {kernel}] = he(seed: 1)\n    weight b1: [3] = normal(std: 0.2, seed: 2)\n    \
             weight k2: [2, 3, 2] = glorot(seed: 3)\n    \
             let h = tanh(conv1d(x, k1, b1, stride: {stride}, padding: {padding}, dilation: {dilation}))\n    \
             let y = conv1d(h, k2, dilation: 2)\n    sum(y * y)\n}}\n\
             scene s {{\n  grid t = times(rate: 19 Hz, duration: 1 s)\n  input x: real[t] = 0.0\n  output out = net(x)\n  grad out wrt net\n}}\n"
        );
        let data = [("x", pseudo_random(19, 6))];
        check_weight_gradients(&src, &data, "out");
        check_against_interpreter(&src, &data);
    }
}

#[test]
fn pooling_layers_have_correct_gradients() {
    for pool in ["max_pool(h, 2)", "max_pool(h, 3, stride: 2)", "avg_pool(h, 3)", "avg_pool(h, window: 2, stride: 1)"] {
        let src = format!(
            "learned net(x) {{\n    weight k1: [2, 1, 3] = he(seed: 7)\n    weight w: [3, 2] = glorot(seed: 8)\n    \
             let h = conv1d(x, k1)\n    let p = {pool}\n    sum(dense(global_avg_pool(p), w) * x3)\n}}\n\
             scene s {{\n  grid t = times(rate: 16 Hz, duration: 1 s)\n  grid c = index(3)\n  input x: real[t] = 0.0\n  input x3: real[c] = 0.0\n  \
             output out = net(x)\n  grad out wrt net\n}}\n"
        );
        let src = src.replace("learned net(x)", "learned net(x, x3)").replace("net(x)\n  grad", "net(x, x3)\n  grad");
        let data = [("x", pseudo_random(16, 9)), ("x3", pseudo_random(3, 10))];
        check_weight_gradients(&src, &data, "out");
        check_against_interpreter(&src, &data);
    }
}

/// `conv2d` with stride, padding and dilation on one- and two-channel
/// images, then 2-D max and average pooling, as a Gravity Spy-style
/// network does on Q-scan images: weight gradients against finite
/// differences, the JIT against the interpreter.
#[test]
fn two_dimensional_convolutions_and_pooling_have_correct_gradients() {
    for (conv, pool) in [
        ("stride: 1, padding: 1", "max_pool2d(h, 2)"),
        ("stride: 2, padding: 2, dilation: 2", "avg_pool2d(h, 2, stride: 1)"),
        ("padding: 0", "max_pool2d(h, window: 3, stride: 2)"),
    ] {
        let src = format!(
            "learned net(x) {{\n    weight k1: [3, 2, 3, 2] = he(seed: 1)\n    weight b1: [3] = normal(std: 0.2, seed: 2)\n    \
             weight k2: [2, 3, 2, 2] = glorot(seed: 3)\n    \
             let img = reshape(stack(x, x * x), 2, 7, 9)\n    \
             let h = tanh(conv2d(img, k1, b1, {conv}))\n    let p = {pool}\n    \
             let y = conv2d(p, k2, padding: 1)\n    sum(y * y) + sum(tanh(y))\n}}\n\
             scene s {{\n  grid t = times(rate: 63 Hz, duration: 1 s)\n  input x: real[t] = 0.0\n  output out = net(x)\n  grad out wrt net\n}}\n"
        );
        let data = [("x", pseudo_random(63, 12))];
        check_weight_gradients(&src, &data, "out");
        check_against_interpreter(&src, &data);
    }
}

/// `conv2d` of a one-channel image `[h, w]` is the sum of its kernel times
/// the image under it; `max_pool2d` takes each square's largest value.
#[test]
fn conv2d_and_max_pool2d_have_pytorch_values() {
    let src = "learned net(x) {\n    weight k: [1, 1, 2, 2] = ones\n    conv2d(reshape(x, 3, 4), k)\n}\n\
               scene s {\n  grid t = index(12)\n  input x: real[t] = 0.0\n  output y = net(x)\n  \
               output m = max_pool2d(reshape(x, 1, 3, 4), 2, stride: 1)\n}\n";
    let model = Model::from_source("conv2d.gw", src).unwrap_or_else(|e| panic!("{e}"));
    let scene = model.scene(None).unwrap();
    let mut run = scene.bind();
    // The image [[0, 1, 2, 3], [4, 5, 6, 7], [8, 9, 10, 11]].
    let x: Vec<f64> = (0..12).map(f64::from).collect();
    run.input_real("x", &x).unwrap();
    let out = run.forward().unwrap();
    let real = |name: &str| match out.value(name).unwrap() {
        Value::RealArray(v) => v.clone(),
        v => panic!("{name} is {v:?}"),
    };
    // Each 2 × 2 square's sum: [[10, 14, 18], [26, 30, 34]] (a 2 × 3 output).
    assert_eq!(real("y"), vec![10.0, 14.0, 18.0, 26.0, 30.0, 34.0]);
    assert_eq!(real("m"), vec![5.0, 6.0, 7.0, 9.0, 10.0, 11.0]);
}

/// `stack` puts a [2, n] convolution, a time series and a one-channel
/// convolution one above the other ([4, n]) for a second convolution.
#[test]
fn stacked_channels_have_correct_gradients() {
    let src = "learned net(x) {\n    weight k1: [2, 1, 3] = he(seed: 1)\n    weight k2: [3, 4, 2] = glorot(seed: 2)\n    \
               weight k3: [1, 1, 3] = normal(std: 0.5, seed: 3)\n    \
               let h = tanh(conv1d(x, k1, padding: 1))\n    \
               let y = conv1d(stack(h, tanh(x), conv1d(x * x, k3, padding: 1)), k2)\n    sum(y * y)\n}\n\
               scene s {\n  grid t = times(rate: 17 Hz, duration: 1 s)\n  input x: real[t] = 0.0\n  output out = net(x)\n  grad out wrt net\n}\n";
    let data = [("x", pseudo_random(17, 11))];
    check_weight_gradients(src, &data, "out");
    check_against_interpreter(src, &data);
}

/// `stack(a, b)` holds `a`'s channels, then `b`'s, exactly.
#[test]
fn stack_puts_its_arguments_one_after_the_other() {
    let src = "scene s {\n  grid t = times(rate: 5 Hz, duration: 1 s)\n  input a: real[t] = 0.0\n  input b: real[t] = 0.0\n  \
               output y = stack(a, stack(b, a * b))\n}\n";
    let model = Model::from_source("stack.gw", src).unwrap();
    let scene = model.scene(None).unwrap();
    let mut run = scene.bind();
    let (a, b) = (pseudo_random(5, 1), pseudo_random(5, 2));
    run.input_real("a", &a).unwrap();
    run.input_real("b", &b).unwrap();
    let out = run.forward().unwrap();
    let Value::RealArray(y) = out.value("y").unwrap() else { panic!("y is not a real array") };
    let ab: Vec<f64> = a.iter().zip(&b).map(|(x, y)| x * y).collect();
    assert_eq!(y, &[a.clone(), b.clone(), ab].concat());
}

#[test]
fn max_pooling_sends_the_gradient_of_a_tie_to_the_first_maximum() {
    // x = [1, 1, 0, 2]: windows of 2 tie in the first; d/dw of sum(max_pool(w * x))
    // with w = ones is x at the chosen positions: [1, 0, 0, 2].
    let src = "learned net(x) {\n    weight w: [4] = ones\n    sum(max_pool(w * x, 2))\n}\n\
               scene s {\n  grid g = index(4)\n  input x: real[g] = 0.0\n  output out = net(x)\n  grad out wrt net\n}\n";
    let model = Model::from_source("ties.gw", src).unwrap();
    let scene = model.scene(None).unwrap();
    let mut run = scene.bind();
    run.input_real("x", &[1.0, 1.0, 0.0, 2.0]).unwrap();
    let out = run.value_and_grad().unwrap();
    assert_eq!(scalar(&out, "out"), 3.0);
    assert_eq!(out.input_grad("out", "net.w").unwrap(), &[1.0, 0.0, 0.0, 2.0]);
}

#[test]
fn cross_entropy_with_logits_of_1e4_is_finite_and_exact() {
    // Logits ±1e4: the softmax saturates; the loss is exactly 0 for the
    // right class and 2e4 for the wrong one, and the gradient is
    // softmax - target (0 or ±1), with no NaN or infinity.
    let src = "use std::nn::{cross_entropy}\nlearned net(x) {\n    weight z: [2] = zeros\n    cross_entropy(z, x)\n}\n\
               scene s {\n  grid c = index(2)\n  input x: real[c] = 0.0\n  output out = net(x)\n  grad out wrt net\n}\n";
    let model = Model::from_source("logits.gw", src).unwrap();
    let scene = model.scene(None).unwrap();
    let mut run = scene.bind();
    for (z, target, loss, grad) in [
        ([1e4, -1e4], [1.0, 0.0], 0.0, [0.0, 0.0]),
        ([1e4, -1e4], [0.0, 1.0], 2e4, [1.0, -1.0]),
        ([-1e4, -1e4], [0.0, 1.0], std::f64::consts::LN_2, [0.5, -0.5]),
    ] {
        run.input_real("net.z", &z).unwrap().input_real("x", &target).unwrap();
        let out = run.value_and_grad().unwrap();
        assert_eq!(scalar(&out, "out"), loss);
        assert_eq!(out.input_grad("out", "net.z").unwrap(), &grad);
    }
}

#[test]
fn physics_params_and_weights_get_gradients_together() {
    // A sine-Gaussian's central frequency (a param) feeds a dense layer;
    // one value-and-gradient call gives d loss / d f0 and d loss / d weights.
    let src = "use std::burst::{sine_gaussian}\n\
               learned head(h) {\n    weight w: [2, 32] = glorot(seed: 4)\n    dense(h, w)\n}\n\
               scene s {\n  grid t = times(rate: 64 Hz, duration: 0.5 s)\n  grid c = index(2)\n  \
               param f0: Hz = 9.0 in 2.0..30.0\n  input y: real[c] = 0.0\n  \
               let h = sine_gaussian(t, f0: f0, q: 3.0, t0: 0.25 s, amp: 1.0, phi: 0.0)\n  \
               output loss = sum((head(h) - y) * (head(h) - y))\n  grad loss wrt [f0, head]\n}\n";
    let model = Model::from_source("joint.gw", src).unwrap();
    let scene = model.scene(None).unwrap();
    let mut run = scene.bind();
    run.input_real("y", &[0.3, -0.2]).unwrap();
    let out = run.value_and_grad().unwrap();
    let g = out.grad("loss", "f0").unwrap();
    let h = 1e-5;
    let mut at = |f0: f64| {
        run.param("f0", f0).unwrap();
        scalar(&run.forward().unwrap(), "loss")
    };
    let fd = (at(9.0 + h) - at(9.0 - h)) / (2.0 * h);
    assert!((g - fd).abs() <= 1e-6 * fd.abs().max(1e-6), "d loss / d f0: {g} vs {fd}");
    assert_eq!(out.input_grad("loss", "head.w").unwrap().len(), 64);
}

#[test]
fn f32_kernels_agree_with_f64_on_a_small_cnn() {
    let src = "use std::nn::{relu, cross_entropy}\n\
               learned net(x) {\n    weight k1: [4, 1, 5] = he(seed: 1)\n    weight b1: [4] = normal(std: 0.1, seed: 2)\n    \
               weight w2: [3, 4] = glorot(seed: 3)\n    \
               let h = relu(conv1d(x, k1, b1, stride: 2, padding: 2))\n    dense(global_avg_pool(max_pool(h, 2)), w2)\n}\n\
               scene s {\n  grid t = times(rate: 32 Hz, duration: 1 s)\n  grid c = index(3)\n  input x: real[t] = 0.0\n  \
               input label: real[c] = 0.0\n  output logits = net(x)\n  output loss = cross_entropy(logits, label)\n  grad loss wrt net\n}\n";
    let model = Model::from_source("f32.gw", src).unwrap();
    let x = pseudo_random(32, 11);
    let mut results = Vec::new();
    use gwml_compiler::ir::Precision;
    for precision in [Precision::F64, Precision::F32, Precision::Mixed] {
        let scene =
            model.scene_with(None, gwml_compiler::Options { precision: Some(precision), math: None, ..Default::default() }).unwrap();
        let mut run = scene.bind();
        run.input_real("x", &x).unwrap().input_real("label", &[0.0, 1.0, 0.0]).unwrap();
        let out = run.value_and_grad().unwrap();
        results.push((scalar(&out, "loss"), out.input_grad("loss", "net.k1").unwrap().to_vec()));
    }
    // Mixed precision has no phases or out-of-range values here: it is f32.
    let (l64, g64) = &results[0];
    let norm = g64.iter().map(|g| g * g).sum::<f64>().sqrt();
    for (l32, g32) in &results[1..] {
        assert!((l64 - l32).abs() <= 1e-5 * l64.abs(), "{l64} vs {l32}");
        for (a, b) in g64.iter().zip(g32) {
            assert!((a - b).abs() <= 1e-5 * norm, "{a} vs {b}");
        }
    }
    assert_eq!(results[1], results[2], "mixed differs from f32 without phases");
}

/// `conv_transpose1d` in PyTorch's layout, directly:
/// `y[o, i·stride + j·dilation − padding] += w[c, o, j] · x[c, i]`.
fn conv_transpose_reference(
    x: &[f64],
    w: &[f64],
    (c_in, c_out, k): (usize, usize, usize),
    (s, p, op, d): (usize, usize, usize, usize),
) -> Vec<f64> {
    let n = x.len() / c_in;
    let len = (n - 1) * s + d * (k - 1) + op + 1 - 2 * p;
    let mut y = vec![0.0; c_out * len];
    for c in 0..c_in {
        for o in 0..c_out {
            for j in 0..k {
                for i in 0..n {
                    let at = (i * s + j * d) as i64 - p as i64;
                    if (0..len as i64).contains(&at) {
                        y[o * len + at as usize] += w[(c * c_out + o) * k + j] * x[c * n + i];
                    }
                }
            }
        }
    }
    y
}

/// `conv_transpose1d` equals the direct scatter formula for strides,
/// paddings, output paddings and dilations, and its weight gradients match
/// finite differences and the interpreter.
#[test]
fn transposed_convolutions_match_the_direct_formula_and_have_correct_gradients() {
    let n = 7;
    for (stride, padding, output_padding, dilation, kernel) in
        [(1, 0, 0, 1, 3), (2, 1, 1, 1, 4), (3, 2, 0, 2, 3), (4, 0, 3, 1, 4), (2, 3, 1, 3, 2)]
    {
        let options = format!("stride: {stride}, padding: {padding}, output_padding: {output_padding}, dilation: {dilation}");
        let src = format!(
            "learned net(x) {{\n    weight w: [2, 3, {kernel}] = normal(std: 1.0, seed: 4)\n    weight b: [3] = normal(std: 0.5, seed: 5)\n    \
             weight w2: [3, 1, 2] = glorot(seed: 6)\n    \
             let h = conv_transpose1d(stack(x, x * x), w, b, {options})\n    \
             let y = tanh(conv_transpose1d(h, w2, stride: 2))\n    sum(y * y)\n}}\n\
             scene s {{\n  grid t = times(rate: {n} Hz, duration: 1 s)\n  input x: real[t] = 0.0\n  output out = net(x)\n  grad out wrt net\n}}\n"
        );
        let x = pseudo_random(n, 12);
        check_weight_gradients(&src, &[("x", x.clone())], "out");
        check_against_interpreter(&src, &[("x", x.clone())]);
        // The layer's values against the direct formula.
        let probe = format!(
            "learned net(x) {{\n    weight w: [2, 3, {kernel}] = normal(std: 1.0, seed: 4)\n    \
             conv_transpose1d(stack(x, x * x), w, {options})\n}}\n\
             scene s {{\n  grid t = times(rate: {n} Hz, duration: 1 s)\n  input x: real[t] = 0.0\n  output y = net(x)\n}}\n"
        );
        let model = Model::from_source("convt.gw", &probe).unwrap();
        let scene = model.scene(None).unwrap();
        let w: Vec<f64> =
            scene.ir().inputs.iter().find(|i| i.name == "net.w").unwrap().default.as_ref().unwrap().iter().map(|z| z.re).collect();
        let mut run = scene.bind();
        run.input_real("x", &x).unwrap();
        let out = run.forward().unwrap();
        let Value::RealArray(y) = out.value("y").unwrap() else { panic!("y is an array") };
        let stacked: Vec<f64> = x.iter().copied().chain(x.iter().map(|v| v * v)).collect();
        let want = conv_transpose_reference(&stacked, &w, (2, 3, kernel), (stride, padding, output_padding, dilation));
        assert_eq!(y.len(), want.len(), "output length for {options}");
        for (a, b) in y.iter().zip(&want) {
            assert!((a - b).abs() <= 1e-12 * (1.0 + b.abs()), "{options}: {a} vs {b}");
        }
    }
}

/// `upsample` repeats each position, `reshape` puts a tensor on a time
/// grid; both have correct gradients.
#[test]
fn upsampling_and_reshaping_have_correct_values_and_gradients() {
    let src = "scene s {\n  grid t = times(rate: 6 Hz, duration: 1 s)\n  grid c = index(3)\n  input x: real[c] = 0.0\n  \
               output y = reshape(upsample(x, 2), t) * spacing(t) / 1 s\n}\n";
    let model = Model::from_source("up.gw", src).unwrap();
    let scene = model.scene(None).unwrap();
    let mut run = scene.bind();
    run.input_real("x", &[1.0, -2.0, 3.0]).unwrap();
    let out = run.forward().unwrap();
    let Value::RealArray(y) = out.value("y").unwrap() else { panic!("y is an array") };
    let want: Vec<f64> = [1.0, 1.0, -2.0, -2.0, 3.0, 3.0].iter().map(|v| v / 6.0).collect();
    for (a, b) in y.iter().zip(&want) {
        assert!((a - b).abs() < 1e-15, "{y:?} vs {want:?}");
    }
    let src = "learned net(x) {\n    weight k: [2, 1, 3] = he(seed: 1)\n    weight w: [4, 2, 3] = glorot(seed: 2)\n    \
               let h = upsample(reshape(tanh(conv1d(x, k, padding: 1)), 2, 5), 3)\n    \
               let y = reshape(conv1d(h, w, padding: 1, stride: 3), t2)\n    sum(y * y * ramp)\n}\n\
               scene s {\n  grid t = times(rate: 5 Hz, duration: 1 s)\n  grid t2 = times(rate: 20 Hz, duration: 1 s)\n  \
               input x: real[t] = 0.0\n  input ramp: real[t2] = 0.0\n  output out = net(x)\n  grad out wrt net\n}\n";
    // The grid reaches the component as an argument, as modules take grids.
    let src = src.replace("learned net(x)", "learned net(x, ramp, t2: s)").replace("net(x)\n  grad", "net(x, ramp, t2)\n  grad");
    let data = [("x", pseudo_random(5, 3)), ("ramp", pseudo_random(20, 4))];
    check_weight_gradients(&src, &data, "out");
    check_against_interpreter(&src, &data);
}

/// `kl_normal` is KL(N(mu, σ²) ‖ N(0, 1)) = ½ (σ² + mu² − 1 − ln σ²) per
/// element, and zero at the prior itself.
#[test]
fn kl_normal_is_the_closed_form_divergence() {
    let src = "use std::nn::{kl_normal}\nscene s {\n  grid g = index(3)\n  input mu: real[g] = 0.0\n  input lv: real[g] = 0.0\n  \
               output kl = kl_normal(mu, lv)\n}\n";
    let model = Model::from_source("kl.gw", src).unwrap();
    let scene = model.scene(None).unwrap();
    let mut run = scene.bind();
    assert_eq!(scalar(&run.forward().unwrap(), "kl"), 0.0, "N(0, 1) against itself");
    let (mu, lv) = ([0.5, -1.0, 2.0], [0.0, 1.0_f64.ln() - 0.7, 2.0]);
    run.input_real("mu", &mu).unwrap().input_real("lv", &lv).unwrap();
    // Each term independently: ln(1/σ) + (σ² + mu²)/2 − ½.
    let want: f64 = mu.iter().zip(&lv).map(|(m, l)| -0.5 * l + (l.exp() + m * m) / 2.0 - 0.5).sum();
    let have = scalar(&run.forward().unwrap(), "kl");
    assert!((have - want).abs() < 1e-14, "{have} vs {want}");
}

/// `slice` takes channels of a tensor, also at an index a module argument
/// gives (`k + 1` with `k` bound to a constant), and its gradient reaches
/// exactly the weights of the rows it took.
#[test]
fn slices_at_module_arguments_take_the_right_rows() {
    let src = "module at(p, k) {\n    sum(slice(p, k + 1, 1))\n}\n\
               learned net(x) {\n    weight w: [4, 3] = glorot(seed: 1)\n    let p = dense(x, w)\n    \
               at(p, 1) * 2.0 + at(p, 0) + sum(slice(reshape(p, 2, 2), 1, 1) * reshape(x2, 1, 2))\n}\n\
               scene s {\n  grid g = index(3)\n  grid h = index(2)\n  input x: real[g] = 0.0\n  input x2: real[h] = 0.0\n  \
               output out = net(x)\n  grad out wrt net\n}\n";
    let src = src.replace("learned net(x)", "learned net(x, x2)").replace("net(x)\n  grad", "net(x, x2)\n  grad");
    let x = pseudo_random(3, 21);
    let x2 = pseudo_random(2, 22);
    let model = Model::from_source("slice.gw", &src).unwrap();
    let scene = model.scene(None).unwrap();
    let w: Vec<f64> =
        scene.ir().inputs.iter().find(|i| i.name == "net.w").unwrap().default.as_ref().unwrap().iter().map(|z| z.re).collect();
    let p: Vec<f64> = (0..4).map(|r| (0..3).map(|c| w[r * 3 + c] * x[c]).sum()).collect();
    let want = 2.0 * p[2] + p[1] + p[2] * x2[0] + p[3] * x2[1];
    let mut run = scene.bind();
    run.input_real("x", &x).unwrap().input_real("x2", &x2).unwrap();
    let have = scalar(&run.forward().unwrap(), "out");
    assert!((have - want).abs() < 1e-14, "{have} vs {want}");
    check_weight_gradients(&src, &[("x", x.clone()), ("x2", x2.clone())], "out");
    check_against_interpreter(&src, &[("x", x), ("x2", x2)]);
}
