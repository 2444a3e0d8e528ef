//! Tests of the transforms, the optimisers and the Fisher matrix.

use super::minimize::dot;
use super::*;
use nalgebra::DMatrix;

/// L = ½ (x - m)ᵀ A (x - m) with a correlated A.
fn quadratic(x: &[f64]) -> Result<(f64, Vec<f64>), ()> {
    let a = [[4.0, 1.0, 0.0], [1.0, 3.0, 0.5], [0.0, 0.5, 2.0]];
    let m = [1.0, -2.0, 0.5];
    let r: Vec<f64> = x.iter().zip(&m).map(|(x, m)| x - m).collect();
    let g: Vec<f64> = (0..3).map(|i| (0..3).map(|j| a[i][j] * r[j]).sum()).collect();
    Ok((0.5 * dot(&r, &g), g))
}

fn rosenbrock(x: &[f64]) -> Result<(f64, Vec<f64>), ()> {
    let (a, b) = (x[0], x[1]);
    let l = (1.0 - a).powi(2) + 100.0 * (b - a * a).powi(2);
    let g = vec![-2.0 * (1.0 - a) - 400.0 * a * (b - a * a), 200.0 * (b - a * a)];
    Ok((l, g))
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

#[test]
fn transforms_round_trip_and_stay_in_bounds() {
    for (x0, b) in [(3.0, Some((1.0, 100.0))), (-0.05, Some((-0.1, 0.1))), (2.0, None), (0.0, None), (5.0, Some((1.0, f64::INFINITY)))] {
        let t = Transform::new(x0, b);
        let u = t.to_u(x0);
        assert!(close(t.to_x(u), x0, 1e-12 * x0.abs().max(1.0)), "{t:?}");
        let h = 1e-6;
        let fd = (t.to_x(u + h) - t.to_x(u - h)) / (2.0 * h);
        assert!(close(fd, t.dx_du(u), 1e-6 * fd.abs().max(1.0)), "{t:?}: {fd} vs {}", t.dx_du(u));
    }
    let t = Transform::new(0.5, Some((0.0, 1.0)));
    for u in [-1e6, -800.0, -40.0, 0.0, 40.0, 800.0, 1e6] {
        let x = t.to_x(u);
        assert!((0.0..=1.0).contains(&x) && x.is_finite(), "{u} -> {x}");
    }
    // A start on a bound maps to a finite u.
    assert!(t.to_u(1.0).is_finite() && t.to_u(0.0).is_finite());
}

#[test]
fn lbfgs_finds_the_minimum_of_a_quadratic() {
    let m = minimize(quadratic, &[0.0, 0.0, 0.0], &[None, None, None], &Settings::new(Algorithm::Lbfgs), |_| {}).unwrap();
    for (x, want) in m.x.iter().zip([1.0, -2.0, 0.5]) {
        assert!(close(*x, want, 1e-7), "{:?}", m);
    }
    assert!(m.stop.converged() && m.steps < 50, "{m:?}");
}

#[test]
fn adam_finds_the_minimum_of_a_quadratic() {
    let mut s = Settings::new(Algorithm::Adam);
    s.learning_rate = 0.1;
    let m = minimize(quadratic, &[0.0, 0.0, 0.0], &[Some((-5.0, 5.0)), None, Some((0.0, 3.0))], &s, |_| {}).unwrap();
    for (x, want) in m.x.iter().zip([1.0, -2.0, 0.5]) {
        assert!(close(*x, want, 1e-4), "{:?}", m);
    }
}

#[test]
fn lbfgs_solves_rosenbrock_unbounded_and_bounded() {
    let s = Settings::new(Algorithm::Lbfgs);
    let m = minimize(rosenbrock, &[-1.2, 1.0], &[None, None], &s, |_| {}).unwrap();
    assert!(close(m.x[0], 1.0, 1e-6) && close(m.x[1], 1.0, 1e-6), "{m:?}");
    assert!(m.stop.converged(), "{m:?}");
    // With bounds (the minimum is inside), through the sigmoid transform.
    let mut seen_out = false;
    let m = minimize(rosenbrock, &[-1.2, 1.0], &[Some((-2.0, 2.0)), Some((-1.0, 3.0))], &s, |p| {
        seen_out |= !(-2.0..=2.0).contains(&p.x[0]) || !(-1.0..=3.0).contains(&p.x[1]);
    })
    .unwrap();
    assert!(close(m.x[0], 1.0, 1e-6) && close(m.x[1], 1.0, 1e-6), "{m:?}");
    assert!(!seen_out);
}

#[test]
fn adam_solves_rosenbrock() {
    let mut s = Settings::new(Algorithm::Adam);
    s.max_steps = 20000;
    s.learning_rate = 0.05;
    let m = minimize(rosenbrock, &[-1.2, 1.0], &[Some((-2.0, 2.0)), Some((-1.0, 3.0))], &s, |_| {}).unwrap();
    assert!(close(m.x[0], 1.0, 1e-3) && close(m.x[1], 1.0, 2e-3), "{m:?}");
}

#[test]
fn a_minimum_on_a_bound_is_approached_without_leaving_it() {
    // L = (x - 3)², x in 0..2: the constrained minimum is x = 2.
    let f = |x: &[f64]| -> Result<(f64, Vec<f64>), ()> {
        assert!((0.0..=2.0).contains(&x[0]), "left the bounds: {}", x[0]);
        Ok(((x[0] - 3.0).powi(2), vec![2.0 * (x[0] - 3.0)]))
    };
    let m = minimize(f, &[1.0], &[Some((0.0, 2.0))], &Settings::new(Algorithm::Lbfgs), |_| {}).unwrap();
    assert!(close(m.x[0], 2.0, 1e-6), "{m:?}");
    // Adam creeps towards a bound (u → ∞) with a decaying rate.
    let m = minimize(f, &[1.0], &[Some((0.0, 2.0))], &Settings::new(Algorithm::Adam), |_| {}).unwrap();
    assert!(close(m.x[0], 2.0, 2e-2), "{m:?}");
}

#[test]
fn errors_at_trial_points_shorten_the_step() {
    // Undefined (an error) for x > 1.5; the minimum is at 1.
    let f = |x: &[f64]| -> Result<(f64, Vec<f64>), String> {
        if x[0] > 1.5 {
            return Err("out of domain".into());
        }
        Ok(((x[0] - 1.0).powi(2), vec![2.0 * (x[0] - 1.0)]))
    };
    let m = minimize(f, &[-3.0], &[None], &Settings::new(Algorithm::Lbfgs), |_| {}).unwrap();
    assert!(close(m.x[0], 1.0, 1e-6), "{m:?}");
    let bad = minimize(f, &[2.0], &[None], &Settings::new(Algorithm::Lbfgs), |_| {});
    assert!(bad.is_err());
}

#[test]
fn fisher_of_a_quadratic_is_its_matrix_and_inverts() {
    let grad = |x: &[f64]| quadratic(x).map(|r| r.1);
    let x = [1.0, -2.0, 0.5];
    let b = [None, None, None];
    let steps = fisher_steps(grad, &x, &b).unwrap();
    let f = fisher_matrix(grad, &x, &b, &steps).unwrap();
    let a = [[4.0, 1.0, 0.0], [1.0, 3.0, 0.5], [0.0, 0.5, 2.0]];
    for i in 0..3 {
        for j in 0..3 {
            assert!(close(f[i][j], a[i][j], 1e-7), "{f:?}");
        }
    }
    let c = invert_fisher(&f).unwrap();
    let inv = DMatrix::from_fn(3, 3, |i, j| a[i][j]).try_inverse().unwrap();
    for i in 0..3 {
        assert!(close(c.sigma[i], inv[(i, i)].sqrt(), 1e-7));
        assert!(close(c.correlation[i][i], 1.0, 1e-12));
        for j in 0..3 {
            assert!(close(c.covariance[i][j], inv[(i, j)], 1e-7));
            assert!(close(c.correlation[i][j], inv[(i, j)] / (inv[(i, i)] * inv[(j, j)]).sqrt(), 1e-7));
        }
    }
}

#[test]
fn fisher_handles_very_different_scales_and_a_bound() {
    // L = ½ (x/1e-4)² + ½ ((y - 1)/1e3)², y in 0..1 (the point is on the bound).
    let grad = |p: &[f64]| -> Result<Vec<f64>, ()> { Ok(vec![p[0] / 1e-8, (p[1] - 1.0) / 1e6]) };
    let x = [0.0, 1.0];
    let b = [None, Some((0.0, 1.0))];
    let steps = fisher_steps(grad, &x, &b).unwrap();
    let f = fisher_matrix(grad, &x, &b, &steps).unwrap();
    let c = invert_fisher(&f).unwrap();
    assert!(close(c.sigma[0] / 1e-4, 1.0, 1e-6) && close(c.sigma[1] / 1e3, 1.0, 1e-6), "{c:?}");
}

#[test]
fn rosenbrock_fisher_at_the_minimum() {
    // Hessian of Rosenbrock at (1, 1): [[802, -400], [-400, 200]].
    let grad = |x: &[f64]| rosenbrock(x).map(|r| r.1);
    let x = [1.0, 1.0];
    let b = [None, None];
    let f = fisher_matrix(grad, &x, &b, &fisher_steps(grad, &x, &b).unwrap()).unwrap();
    let want = [[802.0, -400.0], [-400.0, 200.0]];
    for i in 0..2 {
        for j in 0..2 {
            assert!(close(f[i][j], want[i][j], 1e-3 * want[i][j].abs()), "{f:?}");
        }
    }
    let c = invert_fisher(&f).unwrap();
    // inverse = [[0.5, 1], [1, 2.005]], nearly singular: the 0.1σ steps
    // see Rosenbrock's cubic terms, so allow a few parts per thousand.
    assert!(close(c.sigma[0], 0.5f64.sqrt(), 3e-3) && close(c.sigma[1], 2.005f64.sqrt(), 3e-3), "{c:?}");
}

#[test]
fn indefinite_or_singular_fisher_is_an_error_not_nan() {
    let e = invert_fisher(&[vec![1.0, 2.0], vec![2.0, 1.0]]).unwrap_err();
    match &e {
        FisherError::NotPositiveDefinite { eigenvalues } => {
            assert!(close(eigenvalues[0], -1.0, 1e-12) && close(eigenvalues[1], 3.0, 1e-12))
        }
        other => panic!("{other:?}"),
    }
    assert!(e.to_string().contains("not positive definite"));
    assert!(matches!(invert_fisher(&[vec![1.0, 1.0], vec![1.0, 1.0]]), Err(FisherError::NotPositiveDefinite { .. })));
    assert!(matches!(invert_fisher(&[vec![0.0]]), Err(FisherError::NotPositiveDefinite { .. })));
    assert_eq!(invert_fisher(&[vec![f64::NAN]]), Err(FisherError::NotFinite));
}

/// The fit's Adam is the trainer's: on a bowl with unbounded params started
/// at 0 (where `u = x`), `minimize` takes exactly the steps
/// `optim::Optimizer` takes with the same configuration.
#[test]
fn fits_adam_takes_the_steps_of_the_trainers_adam() {
    use crate::optim::{self, Method, OptimConfig, Schedule};
    let centre = [0.7, -1.3];
    let loss = |x: &[f64]| -> Result<(f64, Vec<f64>), ()> {
        let d: Vec<f64> = x.iter().zip(centre).map(|(x, c)| x - c).collect();
        Ok((d.iter().map(|d| d * d).sum(), d.iter().map(|d| 2.0 * d).collect()))
    };
    let mut s = Settings::new(Algorithm::Adam);
    s.max_steps = 60;
    s.learning_rate = 0.05;
    let mut seen = Vec::new();
    minimize(loss, &[0.0, 0.0], &[None, None], &s, |p| seen.push(p.x.to_vec())).unwrap();
    assert_eq!(seen.len(), 60);

    let config =
        OptimConfig { method: Method::adam(), lr: 0.05, schedule: Schedule::Cosine { total: 60, min_lr: 0.05e-3 }, clip_norm: None };
    let mut adam = optim::Optimizer::new(config, 2).unwrap();
    let mut x = vec![0.0, 0.0];
    for (step, fit_x) in seen.iter().enumerate() {
        let g = loss(&x).unwrap().1;
        adam.step(&mut x, &g).unwrap();
        assert_eq!(&x, fit_x, "step {step}");
    }
}

#[test]
fn a_diagonal_start_fits_params_of_very_different_stiffness() {
    // A loss on a large floor (as a 2 s window's ½Σd² ≈ 4000) whose params
    // are known to parts in 1e5 and 1e1 of their ranges: along the
    // gradient only the stiff one moves, and `rel_tol` stops plain L-BFGS
    // with the loose one far off. Each param's curvature as the first
    // inverse Hessian's diagonal fits both.
    let loss = |x: &[f64]| -> Result<(f64, Vec<f64>), ()> {
        let (a, b) = (1e9, 1.0);
        let (dx, dy) = (x[0] - 0.3001, x[1] - 2.0);
        Ok((4000.0 + 0.5 * (a * dx * dx + b * dy * dy + 1e3 * dx * dy), vec![a * dx + 5e2 * dy, b * dy + 5e2 * dx]))
    };
    let bounds = [Some((0.0, 1.0)), Some((-5.0, 5.0))];
    let plain = Settings { max_steps: 100, rel_tol: 1e-8, ..Settings::new(Algorithm::Lbfgs) };
    let diagonal = Settings { diagonal: true, ..plain.clone() };
    let p = minimize(loss, &[0.3, 0.0], &bounds, &plain, |_| {}).unwrap();
    let d = minimize(loss, &[0.3, 0.0], &bounds, &diagonal, |_| {}).unwrap();
    assert!((d.x[1] - 2.0).abs() < 1e-2 && (d.x[0] - 0.3001).abs() < 1e-6, "diagonal: {d:?}");
    assert!((p.x[1] - 2.0).abs() > 0.1, "plain L-BFGS fitted it too ({p:?}): the test shows nothing");
}

/// A test loss and its gradient.
type Loss = fn(&[f64]) -> Result<(f64, Vec<f64>), ()>;

/// A minimum as L-BFGS would hand it over, stopped at `x`.
fn stopped_at(f: Loss, x: &[f64]) -> Minimum {
    let (loss, grad) = f(x).unwrap();
    Minimum { x: x.to_vec(), loss, grad, steps: 100, evaluations: 120, stop: Stop::Steps }
}

fn hessian_at(f: Loss, x: &[f64], bounds: &[Option<(f64, f64)>]) -> (Vec<Vec<f64>>, Vec<f64>) {
    let steps = fisher_steps(|x: &[f64]| f(x).map(|r| r.1), x, bounds).unwrap();
    (fisher_matrix(|x: &[f64]| f(x).map(|r| r.1), x, bounds, &steps).unwrap(), steps)
}

#[test]
fn one_newton_step_lands_on_a_quadratics_floor() {
    let bounds = [None; 3];
    let x = [3.0, 1.0, -4.0];
    let (fisher, steps) = hessian_at(quadratic, &x, &bounds);
    let settings = NewtonSettings { max_steps: 5, decrease_tol: 1e-12 };
    let p = newton_polish(quadratic, stopped_at(quadratic, &x), fisher, &bounds, &steps, &settings).unwrap();
    assert!(p.converged && p.newton_steps == 1, "{} steps, converged {}", p.newton_steps, p.converged);
    for (a, b) in p.minimum.x.iter().zip([1.0, -2.0, 0.5]) {
        assert!(close(*a, b, 1e-9), "{:?}", p.minimum.x);
    }
    // One trial and a new Hessian (2 gradients per param) on top of what L-BFGS used.
    assert_eq!((p.minimum.evaluations, p.minimum.steps), (120 + 1 + 6, 101));
}

#[test]
fn newton_steps_finish_a_curved_valley_and_stop_within_tolerance() {
    let bounds = [None; 2];
    let x = [0.9, 0.8];
    let (fisher, steps) = hessian_at(rosenbrock, &x, &bounds);
    let settings = NewtonSettings { max_steps: 20, decrease_tol: 1e-14 };
    let p = newton_polish(rosenbrock, stopped_at(rosenbrock, &x), fisher, &bounds, &steps, &settings).unwrap();
    assert!(p.converged && p.minimum.loss < 1e-14, "loss {} after {} steps", p.minimum.loss, p.newton_steps);
    assert!(close(p.minimum.x[0], 1.0, 1e-6) && close(p.minimum.x[1], 1.0, 1e-6), "{:?}", p.minimum.x);
    // One step is not enough at this tolerance: it stops at the budget, lower than it began.
    let few = NewtonSettings { max_steps: 1, ..settings };
    let (fisher, _) = hessian_at(rosenbrock, &x, &bounds);
    let p = newton_polish(rosenbrock, stopped_at(rosenbrock, &x), fisher, &bounds, &steps, &few).unwrap();
    assert!(!p.converged && p.newton_steps == 1 && p.minimum.loss < rosenbrock(&x).unwrap().0);
}

#[test]
fn a_newton_step_stays_inside_the_bounds() {
    // The quadratic's floor is at x0 = 1, beyond the bound 0.5: the step
    // is cut to 99 % of the way there, and the loss still falls.
    let bounds = [Some((-5.0, 0.5)), None, None];
    let x = [0.0, -2.0, 0.5];
    let (fisher, steps) = hessian_at(quadratic, &x, &bounds);
    let settings = NewtonSettings { max_steps: 1, decrease_tol: 1e-12 };
    let p = newton_polish(quadratic, stopped_at(quadratic, &x), fisher, &bounds, &steps, &settings).unwrap();
    assert!(p.minimum.x[0] < 0.5 && p.minimum.x[0] > 0.49, "{:?}", p.minimum.x);
    assert!(p.minimum.loss < quadratic(&x).unwrap().0);
}

#[test]
fn no_newton_step_where_the_hessian_is_not_positive_definite() {
    // A saddle: L = x² − y².
    let saddle = |x: &[f64]| -> Result<(f64, Vec<f64>), ()> { Ok((x[0] * x[0] - x[1] * x[1], vec![2.0 * x[0], -2.0 * x[1]])) };
    let (loss, grad) = saddle(&[0.3, 0.2]).unwrap();
    let start = Minimum { x: vec![0.3, 0.2], loss, grad, steps: 3, evaluations: 4, stop: Stop::Steps };
    let fisher = vec![vec![2.0, 0.0], vec![0.0, -2.0]];
    let settings = NewtonSettings { max_steps: 5, decrease_tol: 1e-12 };
    let p = newton_polish(saddle, start.clone(), fisher, &[None, None], &[1e-3, 1e-3], &settings).unwrap();
    assert!(!p.converged && p.newton_steps == 0 && p.minimum.x == start.x && p.minimum.evaluations == 4);
}
