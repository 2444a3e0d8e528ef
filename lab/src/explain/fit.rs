//! One family's fit to a trigger's window: starts ranked by their match,
//! L-BFGS from the best, a fit's neighbouring modes, and at the end the
//! Fisher matrix, σ and Laplace evidence.

use super::{interpolate, Decimated, Estimate, Family, FamilyFit, FamilyScenes, FreeParam, Seed, Start, LOW_SEARCH_F0};
use gwml_runtime::fit::{
    bic, fit_run, invert_fisher, laplace_evidence, minimize, newton_polish, Algorithm, Minimum, NewtonSettings, Score, Settings, Stop,
};
use gwml_runtime::{Error, Run, Scene, Value};
use std::f64::consts::{FRAC_PI_2, PI, TAU};

/// How many of the best starting points each family refines with L-BFGS.
pub const STARTS_REFINED: usize = 2;

/// How many times a better neighbour's own neighbours are tried.
const NEIGHBOUR_ROUNDS: usize = 3;

/// The Newton steps that finish a polish L-BFGS left short. On 30 Koi
/// Fish (seed 1; ten params, SNR up to 400) the polish stopped at its
/// step limit in 23, and Newton steps then lowered the loss by a median
/// of ~0.3 and by 1.7e4 at most (a Koi at SNR 358). A thousandth of a
/// unit of loss is well below what moves a Bayes factor.
const NEWTON: NewtonSettings = NewtonSettings { max_steps: 8, decrease_tol: 1e-3 };

/// How far inside its bounds (as a fraction of the range) a start puts
/// each shape param.
pub(super) const START_MARGIN: f64 = 0.05;

/// The free params of a family scene (its `grad loss wrt` list): names,
/// units and bounds.
pub(super) fn free_params(scene: &Scene) -> Vec<FreeParam> {
    let f = scene.ir();
    let loss = f.outputs.iter().position(|o| o.name == "loss");
    f.grads
        .iter()
        .filter(|g| Some(g.output) == loss)
        .map(|g| &f.params[g.param])
        .map(|p| (p.name.clone(), p.unit.clone(), p.bounds))
        .collect()
}

/// A run of `scene` on the window's data and PSD.
fn bind<'s>(scene: &'s Scene, window: &Decimated) -> Result<Run<'s>, Error> {
    let mut run = scene.bind();
    run.input_real("d", &window.d)?;
    run.input_real("psd", &window.psd)?;
    Ok(run)
}

fn set(run: &mut Run, names: &[FreeParam], x: &[f64]) -> Result<(), Error> {
    for ((name, _, _), v) in names.iter().zip(x) {
        run.param(name, *v)?;
    }
    Ok(())
}

/// The loss at `x` and its gradient in the free params.
fn loss_and_grad(run: &mut Run, free: &[FreeParam], x: &[f64]) -> Result<(f64, Vec<f64>), Error> {
    set(run, free, x)?;
    let out = run.value_and_grad()?;
    let grad = free.iter().map(|p| out.grad("loss", &p.0).unwrap_or(0.0)).collect();
    Ok((out.scalar("loss")?, grad))
}

/// Where a family's fit begins.
pub(super) enum Begin<'a> {
    /// From its starts for a seed and `more` (built on another family's
    /// fit), ranked together, and the best of `besides` (built on another's,
    /// ranked apart); at the rate of `scenes.search` on the window `low`
    /// (and its rate) where the starts allow ([`Family::low_search`]).
    Search { seed: &'a Seed, more: Vec<Start>, besides: Vec<Start>, low: Option<(&'a Decimated, f64)> },
    /// From a fit's params (`dt`, `snr`, `phi`, shape): the family's
    /// neighbouring modes are tried, and the best is kept.
    Neighbours(Vec<f64>),
    /// From a fit's params, refined and polished there alone.
    Params(Vec<f64>),
}

/// Fits one family to the window at its rate, from where `begin` says:
/// starts ranked by their match, L-BFGS (and, from a fit, its neighbouring
/// modes), Fisher matrix and evidence, with the loss and model of the
/// full-rate window.
pub(super) fn fit_family(
    family: &Family,
    scenes: &FamilyScenes,
    (window, rate): (&Decimated, f64),
    begin: Begin,
) -> Result<FamilyFit, Error> {
    let d = &window.d;
    let mut run = bind(&scenes.fit, window)?;
    let free = free_params(&scenes.fit);
    if free.len() < 3 || free[0].0 != "dt" || free[1].0 != "snr" || free[2].0 != "phi" {
        return Err(Error::Bind(format!("the `{}` scene must fit `dt`, `snr` and `phi` first", family.scene)));
    }
    if let Some(p) = free.iter().enumerate().find(|(i, p)| *i != 2 && p.2.is_none()) {
        return Err(Error::Bind(format!("param `{}` of the `{}` scene needs bounds: they are its prior", p.1 .0, family.scene)));
    }
    let bounds: Vec<Option<(f64, f64)>> = free.iter().map(|p| p.2).collect();
    // Starts keep their shape params a twentieth of the range inside the
    // bounds: the fit maps a bounded param through a sigmoid, whose slope
    // there is a twentieth of its middle's (at a thousandth, a start on a
    // bound, such as a Tomte's asym 1, stalled L-BFGS there: Tomtes 95 ->
    // 90 % with the looser tolerance below). `dt` and `snr` come from the
    // data and keep theirs (an SNR floored at a twentieth of its range
    // started every quiet glitch at SNR 50). Starts measured in the data
    // and a fit's neighbours keep the family's `measured_margin`.
    let within = |margin: f64| {
        let bounds = &bounds;
        move |i: usize, v: f64| match bounds[i] {
            Some((lo, hi)) => {
                let margin = if i < 3 { 1e-3 } else { margin };
                v.clamp(lo + margin * (hi - lo), hi - margin * (hi - lo))
            }
            None => v,
        }
    };
    let (inside, measured) = (within(START_MARGIN), within(family.measured_margin));
    let mut evaluations = 0;
    let settings = refining(family);
    let refine = |run: &mut Run, x0: &[f64], evaluations: &mut usize| {
        let m = minimize(|x: &[f64]| loss_and_grad(run, &free, x), x0, &bounds, &settings, |_| {})?;
        *evaluations += m.evaluations;
        Ok::<_, Error>(m)
    };
    let better = |best: Minimum, m: Minimum| if m.loss < best.loss { m } else { best };
    // A fit from its params is polished; one from a search only where
    // L-BFGS ran out of steps (the others wait for the verdict's contest).
    let from_params = !matches!(begin, Begin::Search { .. });
    let hops = if matches!(begin, Begin::Neighbours(_)) { NEIGHBOUR_ROUNDS } else { 0 };
    // The fit's mode, and the other modes known (from the neighbours).
    let (mut best, rivals) = match begin {
        Begin::Search { seed, more, besides, low } => {
            // 1. Starting points, each with the amplitude and phase that best match the data.
            let mut starts = (family.starts)(seed);
            starts.extend(more);
            // At a lower rate where every start's centre frequency allows.
            let below = |starts: &[Start]| starts.iter().all(|(_, x)| x.first().is_some_and(|f| inside(3, *f) <= LOW_SEARCH_F0));
            let (mut search, d, rate) = match (&scenes.search, low) {
                (Some((scene, _)), Some((window, rate))) if below(&starts) && below(&besides) => {
                    (Some(bind(scene, window)?), &window.d, rate)
                }
                _ => (None, d, rate),
            };
            let searching = search.as_mut().unwrap_or(&mut run);
            let mut ranked = rank_starts(searching, &free, starts, &inside, &mut evaluations)?;
            if let Some(from_data) = family.data_starts {
                ranked.extend(rank_starts(searching, &free, from_data(d, rate, seed), &measured, &mut evaluations)?);
                ranked.sort_by(|a, b| b.0.total_cmp(&a.0));
            }
            let apart = rank_starts(searching, &free, besides, &inside, &mut evaluations)?;
            // 2. L-BFGS from the best starts.
            let mut best: Option<Minimum> = None;
            for (_, x0) in ranked.iter().take(family.refined).chain(apart.first()) {
                let m = refine(searching, x0, &mut evaluations)?;
                best = Some(match best {
                    Some(b) => better(b, m),
                    None => m,
                });
            }
            let mut best = best
                .ok_or_else(|| Error::Bind(format!("no starting point of the `{}` fit has a finite match with the data", family.scene)))?;
            // The lower rate's best, refined at the family's.
            if search.is_some() {
                best = refine(&mut run, &best.x, &mut evaluations)?;
            }
            (best, Vec::new())
        }
        Begin::Neighbours(x) | Begin::Params(x) => {
            let mut minima = vec![refine(&mut run, &x, &mut evaluations)?];
            // Each better neighbour's own neighbours too (a mode two steps away).
            for _ in 0..hops {
                let Some(neighbours) = family.neighbours else { break };
                let best = minima.iter().min_by(|a, b| a.loss.total_cmp(&b.loss)).expect("one minimum");
                let (loss, near) = (best.loss, neighbours(&(best.x[0], best.x[3..].to_vec())));
                // Every neighbour: the best four of a scattered-light
                // fit's twelve by their match, refined alone, left f_motion
                // within 3σ in 93 of 100 (seeds 1 and 6), all twelve in 94 and 96.
                for (_, x0) in rank_starts(&mut run, &free, near, &measured, &mut evaluations)? {
                    minima.push(refine(&mut run, &x0, &mut evaluations)?);
                }
                if minima.iter().all(|m| m.loss >= loss) {
                    break;
                }
            }
            minima.sort_by(|a, b| a.loss.total_cmp(&b.loss));
            // Two minima are one mode when every bounded param agrees to a thousandth of its range.
            let same_mode = |a: &[f64], b: &[f64]| {
                bounds.iter().zip(a.iter().zip(b)).all(|(r, (a, b))| r.is_none_or(|(lo, hi)| (a - b).abs() <= 1e-3 * (hi - lo)))
            };
            let mut modes: Vec<Minimum> = Vec::new();
            for m in minima {
                if modes.iter().all(|kept| !same_mode(&m.x, &kept.x)) {
                    modes.push(m);
                }
            }
            let best = modes.remove(0);
            (best, modes)
        }
    };
    best.x[2] = best.x[2].rem_euclid(TAU);
    // 3. Fisher matrix and errors at the best fit, after a polish (more
    // steps to the tighter tolerance) for a fit from params or one whose
    // L-BFGS ran out of steps; a search's other fits are polished only
    // if they contend for the verdict (`Explainer::explain`), and the
    // rest keep their refined minimum. Newton steps on the Fisher matrix follow where
    // those ran out, and where the Hessian at their end is not positive
    // definite (then kept only if they end where it is: a fit that stopped
    // short of its floor). After a polish that converged with a positive
    // definite Hessian they are not taken: on seed 1's chirps they left
    // two fits with σ(mc) ~1e-5 Msun, a Hessian no smooth likelihood has.
    let polished = from_params || best.stop == Stop::Steps;
    set(&mut run, &free, &best.x)?;
    let steps = if polished { settings.max_steps } else { 0 };
    let mut fit = fit_run(&mut run, Some("loss"), &Settings { rel_tol: 1e-9, max_steps: steps, ..settings.clone() }, |_| {})?;
    evaluations += fit.minimum.evaluations + 2 * free.len() + 2;
    let stalled = polished && fit.minimum.stop == Stop::Steps;
    if polished && (stalled || fit.covariance.is_err()) {
        let newton = |x: &[f64]| loss_and_grad(&mut run, &free, x);
        let polished = newton_polish(newton, fit.minimum.clone(), fit.fisher.clone(), &bounds, &fit.fisher_steps, &NEWTON)?;
        evaluations += polished.minimum.evaluations - fit.minimum.evaluations;
        if polished.newton_steps > 0 {
            let covariance = invert_fisher(&polished.fisher);
            if stalled || covariance.is_ok() {
                fit.covariance = covariance;
                (fit.minimum, fit.fisher) = (polished.minimum, polished.fisher);
            }
        }
    }
    let mut x = fit.minimum.x.clone();
    x[2] = x[2].rem_euclid(TAU);
    let prior: Vec<Option<(f64, f64)>> =
        bounds.iter().enumerate().map(|(i, b)| if i == 2 { Some((x[2] - PI, x[2] + PI)) } else { *b }).collect();
    // Where the loss's Hessian is not positive definite, the fit stopped a
    // little short of its floor (a whistle's span, width and wiggle trade
    // along a curved valley): σ from the model's JᵀJ instead.
    let mut shape = bind(&scenes.shape, window)?;
    let covariance = match fit.covariance {
        Ok(c) => Ok(c),
        Err(e) => {
            let gauss_newton = model_fisher(&mut shape, &free, &x, &prior, &mut evaluations)?;
            // Only where the model describes the data: JᵀJ no stiffer than
            // the Hessian along any param the Hessian curves up.
            let agrees = (0..x.len()).all(|i| fit.fisher[i][i] <= 0.0 || gauss_newton[i][i] <= 2.0 * fit.fisher[i][i]);
            if agrees {
                invert_fisher(&gauss_newton)
            } else {
                Err(e)
            }
        }
    };
    set(&mut shape, &free, &x)?;
    let loss = fit.minimum.loss + window.cut_loss;
    let samples = d.len() * window.factor;
    let score =
        Score { loss, params: x.len(), evidence: laplace_evidence(loss, &x, &fit.fisher, &prior), bic: bic(loss, x.len(), samples) };
    // ln Z is left to this mode's (with the other modes it would gain ln Σ e^{−ΔLₖ}).
    let rivals: Vec<(f64, &[f64])> = rivals.iter().map(|r| (r.loss, r.x.as_slice())).collect();
    let spread = mode_spread((fit.minimum.loss, &x), &rivals);
    let sigma = covariance.as_ref().ok().map(|c| {
        c.sigma.iter().zip(&spread).enumerate().map(|(i, (s, m))| if i == 2 { *s } else { (s * s + m).sqrt() }).collect::<Vec<_>>()
    });
    let params = free
        .iter()
        .enumerate()
        .map(|(i, (name, unit, _))| Estimate {
            name: name.clone(),
            unit: unit.clone(),
            value: x[i],
            sigma: sigma.as_ref().map(|s| s[i]),
            bounds: prior[i].expect("every param of a family has bounds"),
        })
        .collect();
    let Value::RealArray(model) = shape.forward()?.value("model")?.clone() else {
        return Err(Error::Bind(format!("the `{}` scene's `model` is not a real array", family.scene)));
    };
    let model = interpolate(&model, window.factor);
    Ok(FamilyFit {
        family: *family,
        params,
        chi2_dof: 2.0 * loss / (samples - x.len()) as f64,
        score,
        model,
        covariance: covariance.ok().map(|c| c.covariance),
        evaluations: evaluations + 1,
        seconds: 0.0,
        polished,
    })
}

/// A param's bounds, if it has any.
type Range = Option<(f64, f64)>;

/// How many σ from the estimate the profile likelihood is taken at.
const PROFILE_AT: f64 = 3.0;

/// The most L-BFGS steps of each profile fit. Stopping short can only
/// overstate the rise, so σ is widened less, never more. Started where a
/// Gaussian profile has the other params, 25 steps gave Blips (seed 1)
/// f0 96/99 and Q 97/99 within 3σ in 0.150 s per fit, against 94 and
/// 97/99 in 0.226 s from the estimate's other params with 100.
const PROFILE_STEPS: usize = 25;

/// The L-BFGS settings of a family's refining fits. The tolerance is
/// loose enough to rank the starts (|ΔL| ≤ 1e-8 L, ~4e-5 for a 2 s
/// window); [`fit_family`] then polishes the best to 1e-9, where the
/// Fisher matrix and σ are taken. On 30 injections per class (seed 4), 1e-9
/// here took 0.99 s per Blip or Tomte trigger, 1e-8 0.92 s and 1e-7
/// 0.85 s; at 1e-7 fewer Blip fits had a σ (22 of 27 against 26) and,
/// without the polish, scratchy durations were twice as far off.
fn refining(family: &Family) -> Settings {
    Settings { max_steps: 100, rel_tol: 1e-8, diagonal: family.scaled_steps, ..Settings::new(Algorithm::Lbfgs) }
}

/// How far (in units of loss) a point of a profile must fit better than
/// the estimate for the fit to be redone from there ([`widen_to_profiles`]).
const PROFILE_JUMP: f64 = 0.1;

/// Widens the σ of the family's `profiled` params of `fit` (on the
/// window it was fitted to) to their profile likelihood's
/// ([`profile_sigma`]), adding the evaluations spent to the fit's. Only
/// the fits that compete for the verdict pay for it. Returns the params of
/// a profile point that fits better than the estimate by more than
/// [`PROFILE_JUMP`], if one did: the fit stopped in a lesser mode along
/// the valley the profile follows.
pub(super) fn widen_to_profiles(scene: &Scene, window: &Decimated, fit: &mut FamilyFit) -> Result<Option<Vec<f64>>, Error> {
    let mut run = bind(scene, window)?;
    let free = free_params(scene);
    let bounds: Vec<Range> = free.iter().map(|p| p.2).collect();
    let x: Vec<f64> = fit.params.iter().map(|p| p.value).collect();
    let loss = fit.score.loss - window.cut_loss;
    let settings = Settings { max_steps: PROFILE_STEPS, ..refining(&fit.family) };
    let mut better: Option<(f64, Vec<f64>)> = None;
    for (i, p) in free.iter().enumerate().filter(|(_, p)| fit.family.profiled.contains(&p.0.as_str())) {
        let Some(sigma) = fit.params[i].sigma else { continue };
        let fixed = |x: &[f64]| -> Result<(f64, Vec<f64>), Error> {
            let (loss, mut grad) = loss_and_grad(&mut run, &free, x)?;
            grad[i] = 0.0;
            Ok((loss, grad))
        };
        let along = fit.covariance.as_ref().map(|c| c.iter().map(|row| row[i] / c[i][i]).collect());
        let profile = profile_sigma(fixed, (&x, loss), (i, along), sigma, (&bounds, p.2), &settings, fit.family.ridge)?;
        fit.params[i].sigma = Some(profile.sigma);
        fit.evaluations += profile.evaluations;
        if let Some((lower, at)) = profile.best.filter(|(lower, _)| *lower < loss - PROFILE_JUMP) {
            if better.as_ref().is_none_or(|(l, _)| lower < *l) {
                better = Some((lower, at));
            }
        }
    }
    Ok(better.map(|(_, at)| at))
}

/// What [`profile_sigma`] found.
struct Profile {
    /// σ, widened.
    sigma: f64,
    /// Scene evaluations spent.
    evaluations: usize,
    /// The lower of the two profile points (loss, params), if any was taken.
    best: Option<(f64, Vec<f64>)>,
}

/// σ of param `i` widened to the profile likelihood's: the loss minimised
/// over the other params (`fixed`: the loss and its gradient with param
/// `i`'s component zeroed, so L-BFGS holds it) with param `i` at
/// [`PROFILE_AT`] σ either side of the estimate `x` (loss `loss`). Where
/// the profile rises by ΔL < 4.5 there, less than a Gaussian's, σ becomes
/// `PROFILE_AT σ / √(2ΔL)`, so that ±3σ is the profile's ΔL = 4.5 interval
/// on that side (ΔL is floored at ½: a point as good as the estimate
/// makes its distance σ). Never narrowed; a side beyond a bound is
/// skipped. Each profile fit starts from `x` moved along `along` (per
/// unit of param `i`; `C_{ji}/C_{ii}` puts the others where a Gaussian
/// likelihood's profile has them), kept inside their bounds; where the
/// family knows a ridge the likelihood follows ([`super::Ridge`]), a second
/// fit starts on it and the lower of the two is the profile's.
fn profile_sigma(
    mut fixed: impl FnMut(&[f64]) -> Result<(f64, Vec<f64>), Error>,
    (x, loss): (&[f64], f64),
    (i, along): (usize, Option<Vec<f64>>),
    sigma: f64,
    (bounds, range): (&[Range], Range),
    settings: &Settings,
    ridge: Option<super::Ridge>,
) -> Result<Profile, Error> {
    let (mut wider, mut evaluations) = (sigma, 0);
    let mut best: Option<(f64, Vec<f64>)> = None;
    for side in [-1.0, 1.0] {
        let step = side * PROFILE_AT * sigma;
        let inside = sigma > 0.0 && range.is_none_or(|(lo, hi)| lo < x[i] + step && x[i] + step < hi);
        if !inside {
            continue;
        }
        let mut start = x.to_vec();
        for (j, v) in start.iter_mut().enumerate().filter(|(j, _)| *j != i) {
            *v += along.as_ref().map_or(0.0, |a| step * a[j]);
        }
        start[i] = x[i] + step;
        let on_ridge = ridge.and_then(|r| r(x, i, x[i] + step));
        let mut m: Option<Minimum> = None;
        for mut start in std::iter::once(start).chain(on_ridge) {
            for (j, v) in start.iter_mut().enumerate().filter(|(j, _)| *j != i) {
                if let Some((lo, hi)) = bounds[j] {
                    *v = v.clamp(lo + 1e-3 * (hi - lo), hi - 1e-3 * (hi - lo));
                }
            }
            let fitted = minimize(&mut fixed, &start, bounds, settings, |_| {})?;
            evaluations += fitted.evaluations;
            if m.as_ref().is_none_or(|b| fitted.loss < b.loss) {
                m = Some(fitted);
            }
        }
        let m = m.expect("one profile fit a side");
        let rise = (m.loss - loss).max(0.5);
        if rise.is_finite() {
            wider = wider.max(PROFILE_AT * sigma / (2.0 * rise).sqrt());
        }
        if m.loss.is_finite() && best.as_ref().is_none_or(|(l, _)| m.loss < *l) {
            best = Some((m.loss, m.x));
        }
    }
    Ok(Profile { sigma: wider, evaluations, best })
}

/// The variance each param gains from other modes of the likelihood:
/// the mean squared distance from the estimate `best` (its loss and
/// params) of a mixture of it and the `rivals` (loss, params), each
/// weighted by its likelihood `e^{−loss}` with its Laplace volume taken
/// as the estimate's: `Σ wₖ (xₖ − x̂)²`. Added to σ², it is the spread of
/// that mixture about the estimate.
fn mode_spread(best: (f64, &[f64]), rivals: &[(f64, &[f64])]) -> Vec<f64> {
    let weights: Vec<f64> = rivals.iter().map(|(loss, _)| (best.0 - loss).min(0.0).exp()).collect();
    let total = 1.0 + weights.iter().sum::<f64>();
    (0..best.1.len()).map(|i| rivals.iter().zip(&weights).map(|((_, x), w)| w / total * (x[i] - best.1[i]).powi(2)).sum()).collect()
}

/// The Gauss–Newton Fisher matrix of the fit's Gaussian likelihood at
/// `x`: `JᵀJ`, `J` the whitened model's derivatives by central
/// differences, each param stepped by a millionth of its prior's width
/// (one-sided at a bound). Positive semi-definite wherever the fit
/// stopped, unlike the loss's Hessian; it is the curvature the likelihood
/// would have if the model matched the data (where it does not, as a
/// chirp template whose early cycles the data lack, the two part: there
/// the Hessian is the Laplace approximation's).
fn model_fisher(
    run: &mut Run,
    free: &[FreeParam],
    x: &[f64],
    prior: &[Option<(f64, f64)>],
    evaluations: &mut usize,
) -> Result<Vec<Vec<f64>>, Error> {
    let bounds: Vec<Option<(f64, f64)>> = free.iter().map(|p| p.2).collect();
    let mut model_at = |x: &[f64]| -> Result<Vec<f64>, Error> {
        set(run, free, x)?;
        *evaluations += 1;
        match run.forward()?.value("model")? {
            Value::RealArray(m) => Ok(m.clone()),
            _ => Err(Error::Bind("the scene's `model` is not a real array".into())),
        }
    };
    let mut jacobian = Vec::with_capacity(x.len());
    for (i, range) in prior.iter().enumerate() {
        let h = range.map_or(1e-6 * x[i].abs().max(1.0), |(lo, hi)| 1e-6 * (hi - lo));
        // One-sided at a bound (the scene rejects params outside theirs).
        let (lo, hi) = bounds[i].unwrap_or((f64::NEG_INFINITY, f64::INFINITY));
        let (mut up, mut down) = (x.to_vec(), x.to_vec());
        up[i] = (x[i] + h).min(hi);
        down[i] = (x[i] - h).max(lo);
        let step = up[i] - down[i];
        let (mu, md) = (model_at(&up)?, model_at(&down)?);
        jacobian.push(mu.iter().zip(&md).map(|(a, b)| (a - b) / step).collect::<Vec<f64>>());
    }
    Ok(jacobian.iter().map(|a| jacobian.iter().map(|b| a.iter().zip(b).map(|(p, q)| p * q).sum()).collect()).collect())
}

/// Each start as full params (`dt`, `snr`, `phi`, shape), with the SNR and
/// phase that best match the data, and that SNR, best first.
fn rank_starts(
    run: &mut Run,
    free: &[FreeParam],
    starts: Vec<Start>,
    inside: &dyn Fn(usize, f64) -> f64,
    evaluations: &mut usize,
) -> Result<Vec<(f64, Vec<f64>)>, Error> {
    let mut ranked = Vec::new();
    for (dt, shape) in starts {
        let mut x = vec![dt, 1.0, 0.0];
        x.extend(shape);
        let mut x: Vec<f64> = x.iter().enumerate().map(|(i, v)| inside(i, *v)).collect();
        let mut quadrature = [0.0; 2];
        for (k, phi) in [0.0, FRAC_PI_2].into_iter().enumerate() {
            x[2] = phi;
            set(run, free, &x)?;
            quadrature[k] = run.forward()?.scalar("overlap")?;
            *evaluations += 1;
        }
        let rho = quadrature[0].hypot(quadrature[1]);
        if rho.is_finite() {
            x[1] = inside(1, rho);
            x[2] = quadrature[1].atan2(quadrature[0]);
            ranked.push((rho, x));
        }
    }
    ranked.sort_by(|a, b| b.0.total_cmp(&a.0));
    Ok(ranked)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::explain::EXPLAIN_SOURCE;
    use gwml_compiler::Options;
    use gwml_runtime::Model;

    /// A profile flatter than a Gaussian widens σ to its ΔL = 4.5 point at
    /// ±3σ, the other param re-minimised there; a steeper one leaves σ.
    #[test]
    fn sigma_widens_to_a_flat_profile_and_not_to_a_steep_one() {
        // L = ½ (y − x/2)² + ½ x² / (1 + x²/9): curvature 1 in x at the
        // minimum (σ = 1 once y is profiled out), and the profile at x = ±3
        // is 2.25, so σ becomes 3 / √4.5. Without re-minimising y the rise
        // would be 3.375 (σ 1.155).
        let flat = |v: &[f64]| -> Result<(f64, Vec<f64>), Error> {
            let (x, y) = (v[0], v[1]);
            let d = 1.0 + x * x / 9.0;
            let loss = 0.5 * (y - 0.5 * x).powi(2) + 0.5 * x * x / d;
            Ok((loss, vec![0.0, y - 0.5 * x]))
        };
        let settings = Settings::new(Algorithm::Lbfgs);
        let free = [None, None];
        let Profile { sigma, evaluations: used, .. } =
            profile_sigma(flat, (&[0.0, 0.0], 0.0), (0, None), 1.0, (&free, None), &settings, None).unwrap();
        assert!((sigma - 3.0 / 4.5f64.sqrt()).abs() < 1e-6, "σ {sigma}");
        assert!(used > 0);
        // Started where the Gaussian profile has y (x/2), the fits need fewer steps.
        let Profile { sigma: same, evaluations: fewer, .. } =
            profile_sigma(flat, (&[0.0, 0.0], 0.0), (0, Some(vec![1.0, 0.5])), 1.0, (&free, None), &settings, None).unwrap();
        assert!((same - sigma).abs() < 1e-9 && fewer < used, "σ {same}, {fewer} evaluations against {used}");
        // A quartic rises faster than a Gaussian: σ stays.
        let steep =
            |v: &[f64]| -> Result<(f64, Vec<f64>), Error> { Ok((0.5 * v[0] * v[0] + v[0].powi(4) + 0.5 * v[1] * v[1], vec![0.0, v[1]])) };
        assert_eq!(profile_sigma(steep, (&[0.0, 0.0], 0.0), (0, None), 1.0, (&free, None), &settings, None).unwrap().sigma, 1.0);
        // A side beyond the param's bounds is skipped: only +3 is taken.
        let one_side = profile_sigma(flat, (&[0.0, 0.0], 0.0), (0, None), 1.0, (&free, Some((-2.0, 10.0))), &settings, None).unwrap().sigma;
        assert!((one_side - 3.0 / 4.5f64.sqrt()).abs() < 1e-6, "σ {one_side}");
        let none = profile_sigma(flat, (&[0.0, 0.0], 0.0), (0, None), 1.0, (&free, Some((-2.0, 2.0))), &settings, None).unwrap();
        assert_eq!((none.sigma, none.evaluations), (1.0, 0));
        assert!(none.best.is_none());
    }

    /// A profile point below the estimate is reported with its params, so
    /// the fit can be redone from the deeper mode it reached; where both
    /// points lie above the estimate, the lower one is reported and the
    /// caller keeps the fit ([`PROFILE_JUMP`]).
    #[test]
    fn a_profile_that_reaches_a_deeper_mode_reports_it() {
        // In x, a shallow well at 0 (depth 1, curvature 1) and a deeper one
        // at 3.2 (depth 3): the profile at x = +3 lies in the deeper well.
        // y is a nuisance centred on x / 4.
        let two_wells = |v: &[f64]| -> Result<(f64, Vec<f64>), Error> {
            let (x, y) = (v[0], v[1]);
            let (a, b) = ((-0.5 * x * x).exp(), (-2.0 * (x - 3.2).powi(2)).exp());
            let loss = -a - 3.0 * b + 0.5 * (y - 0.25 * x).powi(2);
            Ok((loss, vec![0.0, y - 0.25 * x]))
        };
        let settings = Settings::new(Algorithm::Lbfgs);
        let free = [None, None];
        let p = profile_sigma(two_wells, (&[0.0, 0.0], -1.0), (0, None), 1.0, (&free, None), &settings, None).unwrap();
        let (loss, x) = p.best.expect("a profile point");
        assert!(loss < -1.0 - PROFILE_JUMP, "the profile at +3 should lie below the estimate's -1: {loss}");
        assert!((x[0] - 3.0).abs() < 1e-12 && (x[1] - 0.75).abs() < 1e-6, "{x:?}");
        // A single well: both points lie above the estimate.
        let one_well = |v: &[f64]| -> Result<(f64, Vec<f64>), Error> { Ok((0.5 * v[0] * v[0] + 0.5 * v[1] * v[1], vec![0.0, v[1]])) };
        let (loss, _) = profile_sigma(one_well, (&[0.0, 0.0], 0.0), (0, None), 1.0, (&free, None), &settings, None).unwrap().best.unwrap();
        assert!((loss - 4.5).abs() < 1e-9, "{loss}");
    }

    /// Another mode as likely as the estimate counts half; one 10 units of
    /// loss worse, e^-10 of it; each param moves by its own distance.
    #[test]
    fn other_modes_widen_each_param_by_their_weighted_distance() {
        let best = [1.0, 10.0];
        let even = mode_spread((5.0, &best), &[(5.0, &[3.0, 10.0])]);
        assert_eq!(even, [0.5 * 4.0, 0.0]);
        let far = mode_spread((5.0, &best), &[(15.0, &[3.0, 12.0])]);
        let w = (-10.0f64).exp() / (1.0 + (-10.0f64).exp());
        assert!((far[0] - 4.0 * w).abs() < 1e-15 && (far[1] - 4.0 * w).abs() < 1e-15, "{far:?}");
        // Two rivals, one at the same loss and one e^-1 as likely.
        let two = mode_spread((0.0, &best), &[(0.0, &[2.0, 10.0]), (1.0, &[1.0, 13.0])]);
        let total = 2.0 + (-1.0f64).exp();
        assert!((two[0] - 1.0 / total).abs() < 1e-15 && (two[1] - 9.0 * (-1.0f64).exp() / total).abs() < 1e-15, "{two:?}");
        assert_eq!(mode_spread((0.0, &best), &[]), [0.0, 0.0]);
    }

    #[test]
    fn at_a_noiseless_fit_the_model_fisher_is_the_loss_hessian() {
        // With the data the model itself, the residual is zero at the
        // truth, so the loss's Hessian is exactly JᵀJ: the two estimates
        // must agree to the finite differences' accuracy.
        let knobs = [("window", "0.5 s")].map(|(k, v)| (k.to_string(), v.to_string()));
        let options = Options { knobs: knobs.into_iter().collect(), ..Options::default() };
        let scene = Model::from_source("explain.gw", EXPLAIN_SOURCE).unwrap().scene_with(Some("blip"), options).unwrap();
        let free = free_params(&scene);
        let truth = [0.01, 20.0, 0.7, 180.0, 6.0, 1.4, 0.1];
        let mut run = scene.bind();
        run.input_real("d", &vec![0.0; 2048]).unwrap();
        run.input_real("psd", &vec![1.0; 1025]).unwrap();
        set(&mut run, &free, &truth).unwrap();
        let Value::RealArray(model) = run.forward().unwrap().value("model").unwrap().clone() else { panic!("model is not real") };
        run.input_real("d", &model).unwrap();
        let fit = fit_run(&mut run, Some("loss"), &Settings::new(Algorithm::Lbfgs), |_| {}).unwrap();
        let x = fit.minimum.x.clone();
        assert!(x.iter().zip(&truth).all(|(a, b)| (a - b).abs() < 1e-6 * b.abs().max(1.0)), "the fit left the truth: {x:?}");
        let prior: Vec<Option<(f64, f64)>> = free.iter().map(|p| p.2.or(Some((-PI, PI)))).collect();
        let mut evaluations = 0;
        let jtj = model_fisher(&mut run, &free, &x, &prior, &mut evaluations).unwrap();
        assert_eq!(evaluations, 2 * free.len());
        let h = &fit.fisher;
        for (i, row) in jtj.iter().enumerate() {
            for (j, v) in row.iter().enumerate() {
                let scale = (h[i][i] * h[j][j]).sqrt();
                assert!((v - h[i][j]).abs() < 1e-3 * scale, "({i}, {j}): JᵀJ {v} against the Hessian {} (scale {scale})", h[i][j]);
            }
        }
    }
}
