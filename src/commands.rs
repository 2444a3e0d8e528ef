//! The `gwml` subcommands. Each returns `Err(message)` for the user.

use crate::{BindArgs, CompileArgs, Emit, FitArgs, Format, KnobArgs, OptimizerArg, RunArgs};
use gwml::compiler::front::syntax::print_ast;
use gwml::compiler::ir::BandPurpose;
use gwml::compiler::Options;
use gwml::{Error, Model, Value};
use serde_json::{json, Map};
use std::io::IsTerminal;
use std::path::Path;
use std::time::Instant;

pub(crate) fn render(e: Error) -> String {
    e.render(std::io::stderr().is_terminal())
}

/// Splits `NAME=VALUE` at its first `=` (both sides trimmed, neither empty).
pub(crate) fn knob_assignment(s: &str, flag: &str) -> Result<(String, String), String> {
    match s.split_once('=') {
        Some((n, v)) if !n.trim().is_empty() && !v.trim().is_empty() => Ok((n.trim().to_string(), v.trim().to_string())),
        _ => Err(format!("error: {flag} `{s}`: expected NAME=VALUE, e.g. {flag} pn_order=5")),
    }
}

pub(crate) fn options(k: KnobArgs) -> Result<Options, String> {
    let knobs = k.knobs.iter().map(|s| knob_assignment(s, "--knob")).collect::<Result<Vec<_>, _>>()?;
    Ok(Options {
        knobs,
        precision: k.precision,
        math: k.math,
        multiband: k.multiband,
        relative_binning: k.relative_binning,
        ..Options::default()
    })
}

/// `gwml compile`.
pub fn compile(a: CompileArgs) -> Result<(), String> {
    let t0 = Instant::now();
    let model = Model::from_file(&a.file).map_err(render)?;
    let t_check = t0.elapsed();
    if let Some(Emit::Ast) = a.emit {
        print!("{}", print_ast(&model.program.ast));
        return Ok(());
    }
    let t1 = Instant::now();
    let scene = model.scene_with(a.scene.as_deref(), gwml::compiler::Options { verify: a.verify, ..options(a.knobs)? }).map_err(render)?;
    let t_fwd = t1.elapsed();
    let has_grads = scene.ir().has_gradients();
    let t2 = Instant::now();
    let grad_kernel = if has_grads { Some(scene.gradient_kernel().map_err(render)?) } else { None };
    let t_grad = t2.elapsed();
    match a.emit {
        Some(Emit::Ir) => print!("{}", gwml::compiler::driver::ir_text(&scene.pipeline.pruned)),
        Some(Emit::Adjoint) => print!("{}", gwml::compiler::driver::ir_text(&scene.pipeline.optimized)),
        Some(Emit::Clif) => print!("{}", grad_kernel.unwrap_or(scene.forward_kernel()).clif),
        Some(Emit::Asm) => {
            let ir = if has_grads { &scene.pipeline.optimized } else { scene.forward_ir() };
            print!("{}", gwml::compiler::codegen::disassemble(ir).map_err(|e| render(Error::Codegen(e)))?)
        }
        Some(Emit::Ast) | None => {
            let f = scene.ir();
            println!(
                "scene {}: {} param{}, {} input{}{}, {} output{}, {} gradient{} (precision {}, math {})",
                f.name,
                f.params.len(),
                plural(f.params.len()),
                f.inputs.len(),
                plural(f.inputs.len()),
                match f.inputs.iter().filter(|i| i.is_weight()).count() {
                    0 => String::new(),
                    w => format!(" ({w} weight tensor{})", plural(w)),
                },
                f.outputs.len(),
                plural(f.outputs.len()),
                f.grads.len() + f.input_grads.len(),
                plural(f.grads.len() + f.input_grads.len()),
                f.precision,
                f.math
            );
        }
    }
    if a.stats {
        let s = &scene.pipeline.stats;
        let fk = scene.forward_kernel();
        println!(
            "ops: checked {}, pruned {}, adjoint {}, optimized {} (forward only: {})",
            s.checked_ops,
            s.pruned_ops,
            s.adjoint_ops,
            s.optimized_ops,
            scene.forward_ir().insts.len()
        );
        println!(
            "kernels: forward {} fused loop{}{} ({} clif insts)",
            fk.layout.loops,
            plural(fk.layout.loops),
            split(&fk.layout),
            fk.clif_insts
        );
        if let Some(g) = grad_kernel {
            println!(
                "         forward+gradient {} fused loop{}{} ({} clif insts), {} scratch array{}",
                g.layout.loops,
                plural(g.layout.loops),
                split(&g.layout),
                g.clif_insts,
                scratch(g),
                plural(scratch(g))
            );
        }
        for b in &scene.pipeline.pruned.bands {
            let grid = &scene.pipeline.pruned.grid(b.fine).name;
            match b.purpose {
                BandPurpose::Multiband => {
                    println!("multiband: {} nodes of grid {grid}, phase error {:.1e} rad at the defaults", b.nodes.len(), b.error)
                }
                BandPurpose::RelativeBinning => println!(
                    "relative binning: {} bins of grid {grid}, phase bound {:.2} rad per bin, waveform at {} points per call",
                    b.nodes.len() - 1,
                    b.error,
                    2 * b.nodes.len() - 1
                ),
                BandPurpose::Midpoints => {}
            }
        }
        if let Some(p) = &scene.pipeline.kernel.prelude {
            println!("prelude: {} value{} computed from the data alone, once per bound input", p.outputs.len(), plural(p.outputs.len()));
        }
        let mut times = vec![("parse+check".to_string(), t_check)];
        times.extend(s.times.iter().map(|(n, t)| (n.to_string(), *t)));
        times.push(("codegen forward".into(), t_fwd.saturating_sub(s.times.iter().map(|t| t.1).sum())));
        if has_grads {
            times.push(("codegen gradient".into(), t_grad));
        }
        let line: Vec<String> = times.iter().map(|(n, t)| format!("{n} {:.3} ms", t.as_secs_f64() * 1e3)).collect();
        println!("time: {}", line.join(", "));
    }
    Ok(())
}

fn scratch(k: &gwml::compiler::codegen::Kernel) -> usize {
    k.layout.buffers.iter().filter(|b| b.kind == gwml::compiler::codegen::BufferKind::Scratch).count()
}

/// `", N split at an interval condition"` when a kernel splits loops.
fn split(layout: &gwml::compiler::codegen::Layout) -> String {
    match layout.split_loops {
        0 => String::new(),
        n => match layout.sums_skipped {
            0 => format!(", {n} split at an interval condition"),
            k => format!(", {n} split at an interval condition with {k} sum{} skipped on one side", plural(k)),
        },
    }
}

fn plural(n: usize) -> &'static str {
    if n == 1 {
        ""
    } else {
        "s"
    }
}

pub(crate) fn split_pair<'a>(s: &'a str, flag: &str) -> Result<(&'a str, &'a str), String> {
    s.split_once('=')
        .map(|(a, b)| (a.trim(), b.trim()))
        .filter(|(a, b)| !a.is_empty() && !b.is_empty())
        .ok_or_else(|| format!("error: {flag} expects NAME=VALUE, got `{s}`"))
}

/// `gwml run`.
pub fn run(a: RunArgs) -> Result<(), String> {
    let model = Model::from_file(&a.file).map_err(render)?;
    let scene = model.scene_with(a.scene.as_deref(), options(a.knobs)?).map_err(render)?;
    let mut run = scene.bind();
    bind_args(&mut run, &a.bind)?;
    let out = if a.grad { run.value_and_grad() } else { run.forward() }.map_err(render)?;
    let mut written = Vec::new();
    for s in &a.output {
        let (name, path) = split_pair(s, "--output")?;
        let path = Path::new(path);
        match out.value(name).map_err(render)? {
            Value::RealArray(v) => gwml::npy::write_real(path, v),
            Value::ComplexArray(v) => gwml::npy::write_complex(path, v),
            Value::Real(x) => gwml::npy::write_real(path, &[*x]),
            Value::Complex(z) => gwml::npy::write_complex(path, &[*z]),
        }
        .map_err(render)?;
        written.push((name.to_string(), path.display().to_string()));
    }
    let f = scene.ir();
    if a.format == Format::Json {
        let params: Map<String, serde_json::Value> = out.params.iter().map(|(n, v)| (n.clone(), json!(v))).collect();
        let mut outputs = Map::new();
        for (n, v) in &out.values {
            let file = written.iter().find(|(w, _)| w == n).map(|(_, p)| p.clone());
            let j = match v {
                Value::Real(x) => json!(x),
                Value::Complex(z) => json!({"re": z.re, "im": z.im}),
                Value::RealArray(a) => json!({"len": a.len(), "npy": file}),
                Value::ComplexArray(a) => json!({"len": a.len(), "complex": true, "npy": file}),
            };
            outputs.insert(n.clone(), j);
        }
        let mut grads: Map<String, serde_json::Value> = Map::new();
        for (o, p, g) in &out.grads {
            let entry = grads.entry(o.clone()).or_insert_with(|| json!({}));
            entry[p] = json!(g);
        }
        println!(
            "{}",
            serde_json::to_string_pretty(&json!({"params": params, "outputs": outputs, "grads": grads})).expect("JSON of numbers")
        );
        return Ok(());
    }
    println!("scene {} (precision {}, math {})", f.name, f.precision, f.math);
    let w = out.params.iter().map(|p| p.0.len()).chain(out.values.iter().map(|v| v.0.len())).max().unwrap_or(0);
    if !out.params.is_empty() {
        println!("params:");
        for ((n, v), p) in out.params.iter().zip(&f.params) {
            println!("{}", format!("  {n:w$} = {v} {}", unit(&p.unit)).trim_end());
        }
    }
    println!("outputs:");
    for ((n, v), o) in out.values.iter().zip(&f.outputs) {
        let file = written.iter().find(|(w, _)| w == n).map(|(_, p)| format!(" -> {p}")).unwrap_or_default();
        let text = match v {
            Value::Real(x) => format!("{x}"),
            Value::Complex(z) => format!("{} {:+}i", z.re, z.im),
            Value::RealArray(a) => summary(a.len(), a.iter().copied(), false),
            Value::ComplexArray(a) => summary(a.len(), a.iter().map(|z| z.norm()), true),
        };
        println!("{}", format!("  {n:w$} = {text} {}{file}", unit(&o.unit)).trim_end());
    }
    if !out.grads.is_empty() {
        println!("gradients:");
        let gw = out.grads.iter().map(|(o, p, _)| o.len() + p.len() + 8).max().unwrap_or(0);
        for ((o, p, g), pi) in out.grads.iter().zip(f.grads.iter().map(|g| &f.params[g.param])) {
            let label = format!("d{o}/d{p}");
            let per = if pi.unit == "1" { String::new() } else { format!("per {}", pi.unit) };
            println!("{}", format!("  {label:gw$} = {g} {per}").trim_end());
        }
    }
    if !out.input_grads.is_empty() {
        println!("weight gradients:");
        let gw = out.input_grads.iter().map(|(o, i, _)| o.len() + i.len() + 3).max().unwrap_or(0);
        for (o, i, g) in &out.input_grads {
            let label = format!("d{o}/d{i}");
            let (lo, hi) = g.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| (a.min(*x), b.max(*x)));
            let norm = g.iter().map(|x| x * x).sum::<f64>().sqrt();
            println!("  {label:gw$} = {} values in [{lo:e}, {hi:e}], L2 norm {norm:e}", g.len());
        }
    }
    Ok(())
}

fn unit(u: &str) -> String {
    if u == "1" {
        String::new()
    } else {
        format!("[{u}]")
    }
}

fn summary(len: usize, xs: impl Iterator<Item = f64> + Clone, complex: bool) -> String {
    let min = xs.clone().fold(f64::INFINITY, f64::min);
    let max = xs.fold(f64::NEG_INFINITY, f64::max);
    let what = if complex { "complex array, |z|" } else { "array" };
    format!("{what} of {len}: min {min:.6e}, max {max:.6e} (write it with --output NAME=FILE.npy)")
}

/// Binds `--set` and `--input` values to a run (as `gwml run` does).
pub(crate) fn bind_args(run: &mut gwml::Run, bind: &BindArgs) -> Result<(), String> {
    for s in &bind.set {
        let (name, value) = split_pair(s, "--set")?;
        run.param_quantity(name, value).map_err(|e| format!("error: --set {s}: {}", render(e).trim_start_matches("error: ")))?;
    }
    for s in &bind.input {
        let (name, path) = split_pair(s, "--input")?;
        if let Some((kind, file)) = spectrum_source(path) {
            let spectrum = gwml::spectrum::Spectrum::read(file, kind).map_err(render)?;
            run.input_spectrum(name, &spectrum).map_err(render)?;
            continue;
        }
        let data = gwml::npy::read(Path::new(path)).map_err(render)?;
        if data.complex {
            run.input_complex(name, &data.values).map_err(render)?;
        } else {
            let re: Vec<f64> = data.values.iter().map(|z| z.re).collect();
            run.input_real(name, &re).map_err(render)?;
        }
    }
    Ok(())
}

/// Whether `--input NAME=SOURCE` names a two-column spectrum text file
/// (`asd:FILE` is an ASD, squared; `psd:FILE` or any other file that is not
/// a NumPy file is a PSD), and which; `None` for a `.npy` file.
fn spectrum_source(source: &str) -> Option<(gwml::spectrum::Kind, &str)> {
    use gwml::spectrum::Kind;
    if let Some(file) = source.strip_prefix("asd:") {
        return Some((Kind::Asd, file));
    }
    if let Some(file) = source.strip_prefix("psd:") {
        return Some((Kind::Psd, file));
    }
    let path = Path::new(source);
    let npy_magic = || {
        let mut magic = [0u8; 6];
        std::fs::File::open(path).and_then(|mut f| std::io::Read::read_exact(&mut f, &mut magic)).is_ok() && &magic == b"\x93NUMPY"
    };
    let npy = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("npy")) || npy_magic();
    (!npy).then_some((Kind::Psd, source))
}

/// `gwml fit`.
pub fn fit(a: FitArgs) -> Result<(), String> {
    use gwml_runtime::fit::{fit_run, Algorithm, Settings};
    let model = Model::from_file(&a.file).map_err(render)?;
    let scene = model.scene_with(a.scene.as_deref(), options(a.knobs)?).map_err(render)?;
    let mut run = scene.bind();
    bind_args(&mut run, &a.bind)?;
    let optimizer = match a.optimizer {
        OptimizerArg::Lbfgs => Algorithm::Lbfgs,
        OptimizerArg::Adam => Algorithm::Adam,
    };
    let mut settings = Settings::new(optimizer);
    if let Some(n) = a.steps {
        settings.max_steps = n;
    }
    if let Some(lr) = a.learning_rate {
        if !(lr.is_finite() && lr > 0.0) {
            return Err(format!("error: --learning-rate must be a positive number, got {lr}"));
        }
        settings.learning_rate = lr;
    }
    let every = match optimizer {
        Algorithm::Lbfgs => 10,
        Algorithm::Adam => 100,
    };
    let f = scene.ir();
    let t0 = Instant::now();
    let quiet = a.quiet;
    // The free params' names, for the progress lines.
    let mut free_names: Vec<String> = Vec::new();
    if let Some(oi) = a.output.as_deref().map_or_else(
        || gwml_runtime::fit::candidate_outputs(&run).first().and_then(|n| f.outputs.iter().position(|o| &o.name == n)),
        |n| f.outputs.iter().position(|o| o.name == n),
    ) {
        free_names = f.grads.iter().filter(|g| g.output == oi).map(|g| f.params[g.param].name.clone()).collect();
    }
    let progress = |p: &gwml_runtime::fit::Progress| {
        if quiet || (!p.step.is_multiple_of(every) && p.step != 1) {
            return;
        }
        let xs: Vec<String> = free_names.iter().zip(p.x).map(|(n, x)| format!("{n}={x:.6e}")).collect();
        eprintln!(
            "step {:5}  loss {:.10e}  |grad_u| {:.3e}  {}  ({:.1} s)",
            p.step,
            p.loss,
            p.grad_norm,
            xs.join(" "),
            t0.elapsed().as_secs_f64()
        );
    };
    let r = fit_run(&mut run, a.output.as_deref(), &settings, progress).map_err(render)?;
    let opt_name = match optimizer {
        Algorithm::Lbfgs => "lbfgs",
        Algorithm::Adam => "adam",
    };
    let names: Vec<&str> = r.free.iter().map(|p| p.name.as_str()).collect();
    let m = &r.minimum;
    if a.format == Format::Json {
        let cov = r.covariance.as_ref().ok();
        let mut params = Map::new();
        for (i, p) in r.free.iter().enumerate() {
            params.insert(
                p.name.clone(),
                json!({
                    "value": m.x[i],
                    "sigma": cov.map(|c| c.sigma[i]),
                    "start": p.start,
                    "unit": p.unit,
                    "bounds": p.bounds.map(|(lo, hi)| json!([lo, hi])),
                    "grad": m.grad[i],
                }),
            );
        }
        let fixed: Map<String, serde_json::Value> = r.fixed.iter().map(|(n, v)| (n.clone(), json!(v))).collect();
        let fisher = match &r.covariance {
            Ok(c) => json!({
                "params": names,
                "matrix": r.fisher,
                "steps": r.fisher_steps,
                "positive_definite": true,
                "covariance": c.covariance,
                "correlation": c.correlation,
                "condition": c.condition,
            }),
            Err(e) => json!({
                "params": names,
                "matrix": r.fisher,
                "steps": r.fisher_steps,
                "positive_definite": false,
                "error": e.to_string(),
                "eigenvalues": match e {
                    gwml_runtime::fit::FisherError::NotPositiveDefinite { eigenvalues } => json!(eigenvalues),
                    gwml_runtime::fit::FisherError::NotFinite => serde_json::Value::Null,
                },
            }),
        };
        let j = json!({
            "scene": f.name,
            "output": r.output,
            "optimizer": opt_name,
            "steps": m.steps,
            "evaluations": m.evaluations,
            "stop": m.stop.to_string(),
            "converged": m.stop.converged(),
            "start_loss": r.start_loss,
            "loss": m.loss,
            "params": params,
            "fixed": fixed,
            "fisher": fisher,
        });
        println!("{}", serde_json::to_string_pretty(&j).expect("JSON of numbers"));
        return Ok(());
    }
    println!(
        "scene {}: minimised `{}` over {} param{} with {}",
        f.name,
        r.output,
        r.free.len(),
        plural(r.free.len()),
        match optimizer {
            Algorithm::Lbfgs => "L-BFGS",
            Algorithm::Adam => "Adam",
        }
    );
    println!("stopped after {} step{} ({} evaluations): {}", m.steps, plural(m.steps), m.evaluations, m.stop);
    println!("{} = {} (start {})", r.output, num(m.loss), num(r.start_loss));
    let w = names.iter().map(|n| n.len()).max().unwrap_or(0);
    match &r.covariance {
        Ok(c) => {
            println!("estimate (± 1σ from the Fisher matrix, the Hessian of `{}`):", r.output);
            for (i, p) in r.free.iter().enumerate() {
                println!("  {:w$} = {} ± {:.3e} {}", p.name, num(m.x[i]), c.sigma[i], unit(&p.unit));
            }
            println!("correlation:");
            let head: Vec<String> = names.iter().map(|n| format!("{n:>8}")).collect();
            println!("  {:w$} {}", "", head.join(""));
            for (i, n) in names.iter().enumerate() {
                let row: Vec<String> = c.correlation[i].iter().map(|v| format!("{v:8.3}")).collect();
                println!("  {n:w$} {}", row.join(""));
            }
        }
        Err(e) => {
            println!("estimate:");
            for (i, p) in r.free.iter().enumerate() {
                println!("  {:w$} = {} {}", p.name, num(m.x[i]), unit(&p.unit));
            }
            println!("no uncertainties: {e}");
        }
    }
    if !r.fixed.is_empty() {
        let fixed: Vec<String> = r.fixed.iter().map(|(n, v)| format!("{n} = {}", num(*v))).collect();
        println!("fixed: {}", fixed.join(", "));
    }
    if !m.stop.converged() {
        println!("warning: the optimiser did not converge; raise --steps or start closer (--set)");
    }
    Ok(())
}

/// A number in plain notation when that is short, scientific otherwise.
fn num(x: f64) -> String {
    if x == 0.0 || (1e-3..1e6).contains(&x.abs()) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

/// `gwml tradeoff`.
pub fn tradeoff(a: crate::TradeoffArgs) -> Result<(), String> {
    use gwml::compiler::ir::{Multiband, RelativeBinning};
    use gwml_lab::tradeoff::{
        all_configs, csv, sweep, table, with_algorithms, with_knob_sweeps, Config, Settings, DEFAULT_MULTIBAND, DEFAULT_RELATIVE_BINNING,
    };
    let model = Model::from_file(&a.file).map_err(render)?;
    // The algorithmic settings are swept by default only where they
    // apply: multibanding for a scene with a waveform phase over a grid,
    // relative binning for one with a likelihood sum over a waveform.
    let probe = |options: Options| model.scene_with(a.scene.as_deref(), options).map_err(render);
    let multiband = if !a.multiband.is_empty() {
        a.multiband.clone()
    } else if probe(Options { multiband: Some(DEFAULT_MULTIBAND[2]), ..Default::default() })?.forward_ir().bands.is_empty() {
        vec![Multiband::Off]
    } else {
        DEFAULT_MULTIBAND.to_vec()
    };
    let relative_binning = if !a.relative_binning.is_empty() {
        a.relative_binning.clone()
    } else if a.multiband.is_empty()
        && !probe(Options { relative_binning: Some(DEFAULT_RELATIVE_BINNING[1]), ..Default::default() })?.ir().bands.is_empty()
    {
        std::iter::once(RelativeBinning::Off).chain(DEFAULT_RELATIVE_BINNING).collect()
    } else {
        vec![RelativeBinning::Off]
    };
    // Each algorithm on its own: multibanding with relative binning off,
    // and relative binning with multibanding off.
    let mut algorithms: Vec<(Multiband, RelativeBinning)> = multiband.iter().map(|&m| (m, RelativeBinning::Off)).collect();
    algorithms.extend(relative_binning.iter().filter(|&&r| r != RelativeBinning::Off).map(|&r| (Multiband::Off, r)));
    let configs: Vec<Config> = all_configs()
        .into_iter()
        .filter(|c| a.precision.is_empty() || a.precision.contains(&c.precision))
        .filter(|c| a.math.is_empty() || a.math.contains(&c.math))
        .collect();
    let configs = with_algorithms(configs, &algorithms);
    let mut sweeps = Vec::new();
    for s in &a.sweep {
        let (name, values) = knob_assignment(s, "--sweep")?;
        sweeps.push((name, values.split(',').map(|v| v.trim().to_string()).filter(|v| !v.is_empty()).collect::<Vec<_>>()));
    }
    // Each swept value must be a valid override: report a bad name or value
    // once, with its source, instead of in every row.
    for (name, values) in &sweeps {
        if values.is_empty() {
            return Err(format!("error: --sweep {name}: no values; write --sweep {name}=V1,V2,..."));
        }
        for v in values {
            model
                .scene_with(a.scene.as_deref(), Options { knobs: vec![(name.clone(), v.clone())], ..Default::default() })
                .map_err(render)?;
        }
    }
    let mut fixed: Vec<(String, String)> = Vec::new();
    for k in &a.knob {
        let (name, value) = knob_assignment(k, "--knob")?;
        if sweeps.iter().any(|(n, _)| *n == name) {
            return Err(format!("error: knob `{name}` is both set (--knob) and swept (--sweep); give one of them"));
        }
        fixed.retain(|(n, _)| *n != name);
        fixed.push((name, value));
    }
    if !fixed.is_empty() {
        model.scene_with(a.scene.as_deref(), Options { knobs: fixed.clone(), ..Default::default() }).map_err(render)?;
    }
    let configs = with_knob_sweeps(configs, &sweeps)
        .into_iter()
        .map(|c| Config { knobs: fixed.iter().cloned().chain(c.knobs).collect(), ..c })
        .collect();
    let settings = Settings { configs, reps: a.reps, psd: a.psd.clone(), knobs: fixed };
    let bind = |run: &mut gwml::Run| bind_args(run, &a.bind).map_err(Error::Bind);
    let mut progress = |i: usize, count: usize, c: &Config| eprintln!("[{}/{count}] {}", i + 1, c.label());
    let rows = sweep(&model, a.scene.as_deref(), &settings, &bind, &mut progress).map_err(|e| match e {
        Error::Bind(m) if m.starts_with("error:") => m,
        other => render(other),
    })?;
    print!("{}", table(&rows));
    println!(
        "(* = Pareto-optimal in time and error; speed-up of value+grad (the differentiated outputs and their gradients only), or forward (every output), relative to f64 exact; median of {} calls)",
        a.reps
    );
    if let Some(p) = &a.csv {
        std::fs::write(p, csv(&rows)).map_err(|e| format!("error: cannot write {}: {e}", p.display()))?;
    }
    if let Some(p) = &a.json {
        let items: Vec<serde_json::Value> = rows
            .iter()
            .map(|r| {
                let knobs: serde_json::Map<String, serde_json::Value> = r.config.knobs.iter().map(|(n, v)| (n.clone(), json!(v))).collect();
                json!({"precision": r.config.precision.to_string(), "math": r.config.math.to_string(),
                       "multiband": r.config.multiband.to_string(),
                       "relative_binning": r.config.relative_binning.to_string(), "knobs": knobs, "forward_us": r.forward_us,
                       "grad_us": r.grad_us, "output_error": r.output_error, "grad_error": r.grad_error, "mismatch": r.mismatch, "delta_loss": r.delta_loss, "pareto": r.pareto,
                       "failure": r.failure})
            })
            .collect();
        let text = serde_json::to_string_pretty(&items).map_err(|e| format!("error: {e}"))?;
        std::fs::write(p, text + "\n").map_err(|e| format!("error: cannot write {}: {e}", p.display()))?;
    }
    if let Some(p) = &a.plot {
        let points: Vec<(f64, f64, String, bool)> = rows.iter().map(|r| (r.time_us(), r.error(), r.config.label(), r.pareto)).collect();
        gwml_lab::plot::scatter_loglog(
            p,
            "time against error (red: Pareto-optimal)",
            "time per call (µs)",
            "error vs f64 exact",
            &points,
            1e-17,
        )?;
    }
    Ok(())
}
