//! The driver: the stage order, and nothing else.
//!
//! parse (+ imports) → resolve modules → check + lower each scene →
//! prune → relbin → cutsum → multiband → adjoint → simplify → stage → specialise → rescale → (codegen, in
//! [`crate::codegen`]). Every composition of passes is here
//! ([`GRADIENT_PASSES`], [`FORWARD_PASSES`]); after each pass the IR is
//! verified in debug builds, or when asked ([`Options::verify`],
//! `GWML_VERIFY=1`).

use crate::check::{collect_modules, Checker, KnobOverride};
use crate::front::diagnostics::{render_all, Diagnostic};
use crate::front::source::{FileId, SourceMap, Span};
use crate::front::stdlib;
use crate::front::syntax::{self, ast};
use crate::ir::{Function, Precision};
use crate::passes;
use std::collections::HashMap;
use std::fmt;
use std::sync::OnceLock;
use std::time::{Duration, Instant};

/// Compilation failed; holds every diagnostic and the sources they point into.
#[derive(Clone, Debug)]
pub struct CompileError {
    /// What went wrong.
    pub diagnostics: Vec<Diagnostic>,
    /// The sources, for rendering.
    pub sources: SourceMap,
}

impl CompileError {
    /// Renders every diagnostic with ariadne.
    pub fn render(&self, color: bool) -> String {
        render_all(&self.diagnostics, &self.sources, color)
    }
}

impl fmt::Display for CompileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.render(false))
    }
}

impl std::error::Error for CompileError {}

/// Why [`Program::pipeline`] could not prepare a scene.
#[derive(Clone, Debug)]
pub enum PipelineError {
    /// No such scene, or an option names something the scene lacks.
    Scene(String),
    /// A knob override does not parse or check; its diagnostics point into
    /// the scene or into the override's text.
    Compile(CompileError),
    /// A pass produced IR the verifier rejects: a compiler bug.
    Internal {
        /// The pass that ran last.
        pass: &'static str,
        /// What the verifier found.
        message: String,
    },
}

impl fmt::Display for PipelineError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PipelineError::Scene(s) => f.write_str(s),
            PipelineError::Compile(c) => c.fmt(f),
            PipelineError::Internal { pass, message } => {
                write!(
                    f,
                    "internal compiler error: the IR after pass `{pass}` is invalid: {message} (please report this with the .gw file)"
                )
            }
        }
    }
}

impl std::error::Error for PipelineError {}

/// A parsed and checked program: its files, AST, and every scene lowered to IR.
#[derive(Clone, Debug)]
pub struct Program {
    /// All source files (the user's first, then imported stdlib files).
    pub sources: SourceMap,
    /// The user's file, parsed.
    pub ast: ast::SourceFileAst,
    /// The imported stdlib files, parsed (their modules are in scope).
    std_asts: Vec<ast::SourceFileAst>,
    scenes: Vec<Function>,
}

/// Per-scene compile options.
#[derive(Clone, Debug, Default)]
pub struct Options {
    /// Overrides the scene's `precision` setting.
    pub precision: Option<Precision>,
    /// Overrides the scene's `math` setting.
    pub math: Option<crate::ir::MathMode>,
    /// Overrides the scene's `multiband` setting.
    pub multiband: Option<crate::ir::Multiband>,
    /// Overrides the scene's `relative_binning` setting.
    pub relative_binning: Option<crate::ir::RelativeBinning>,
    /// Overrides of the scene's `knob` values: name and value as source text
    /// (`("df", "0.25 Hz")`); the scene is checked and lowered again with them.
    pub knobs: Vec<(String, String)>,
    /// Compile only these outputs (and their gradients); `None` for all.
    /// `gwml tradeoff` times value-and-gradient this way, as a sampler or
    /// optimiser calls it, without the array outputs kept for its error
    /// columns.
    pub outputs: Option<Vec<String>>,
    /// Verify the IR after every pass, as debug builds and `GWML_VERIFY=1`
    /// do (`gwml compile --verify`).
    pub verify: bool,
    /// Params fixed at compile time (name, value in the declared unit):
    /// each becomes a constant and leaves the scene's params, so what it
    /// alone determines is folded into tables. A scan's classifier freezes
    /// its trained template params this way.
    pub frozen_params: Vec<(String, f64)>,
}

/// Instruction counts and times of each stage, for `gwml compile --stats`.
#[derive(Clone, Debug, Default)]
pub struct Stats {
    /// Instructions after checking (every definition in the scene).
    pub checked_ops: usize,
    /// After pruning to the requested outputs and gradients.
    pub pruned_ops: usize,
    /// After the adjoint pass.
    pub adjoint_ops: usize,
    /// After simplification (the IR code generation sees).
    pub optimized_ops: usize,
    /// Time per stage, in pipeline order; then `verify`, the verifier's
    /// total over every pass, when it ran.
    pub times: Vec<(&'static str, Duration)>,
}

/// One scene through every IR stage.
#[derive(Clone, Debug)]
pub struct ScenePipeline {
    /// As checked and lowered (all definitions).
    pub checked: Function,
    /// Pruned to what outputs need (and multibanded, when the scene asks).
    pub pruned: Function,
    /// With adjoints appended.
    pub adjoint: Function,
    /// Simplified, specialised and rescaled: the whole computation.
    pub optimized: Function,
    /// What the gradient kernel runs: `optimized`, or its prelude and
    /// per-call parts when values computed from the data alone were split off.
    pub kernel: KernelIr,
    /// Counts and times.
    pub stats: Stats,
    /// Whether the IR is verified after every pass (also by [`ScenePipeline::forward`]).
    pub verify: bool,
}

impl Program {
    /// Parses `text` (named `name` in diagnostics), loads its imports, checks
    /// every module and scene, and lowers every scene to IR.
    pub fn parse(name: &str, text: &str) -> Result<Program, CompileError> {
        let mut sources = SourceMap::new();
        let file = sources.add(name, text);
        let (ast, mut diags) = syntax::parse(text, file);
        let mut std_asts: Vec<(String, ast::SourceFileAst)> = Vec::new();
        load_imports(&ast, &mut sources, &mut std_asts, &mut diags);
        let mut program = Program { sources, ast, std_asts: std_asts.into_iter().map(|(_, a)| a).collect(), scenes: Vec::new() };
        let modules = program.modules(&mut diags);
        let mut scenes = Vec::new();
        {
            let mut checker = Checker::new(modules.clone());
            // Source order, so diagnostics come out in the same order every run.
            let mut in_order: Vec<&ast::ModuleDef> = modules.values().copied().collect();
            in_order.sort_by_key(|m| (m.span.file, m.span.start));
            for m in in_order {
                checker.resolve_module(m);
            }
            diags.append(&mut checker.take_diagnostics());
            let mut seen = HashMap::new();
            for item in &program.ast.items {
                if let ast::Item::Scene(s) = item {
                    if let Some(prev) = seen.insert(s.name.node.clone(), s.name.span) {
                        diags.push(
                            Diagnostic::error(s.name.span, format!("scene `{}` is defined twice", s.name.node))
                                .with_secondary(prev, "first defined here")
                                .with_help("rename one of them"),
                        );
                        continue;
                    }
                    match Checker::new(modules.clone()).lower_scene(s, &[]) {
                        Ok(f) => scenes.push(f),
                        Err(mut d) => diags.append(&mut d),
                    }
                }
            }
        }
        if !diags.is_empty() {
            dedup(&mut diags);
            return Err(CompileError { diagnostics: diags, sources: program.sources });
        }
        program.scenes = scenes;
        Ok(program)
    }

    /// Every module in scope: each loaded stdlib file's, then the user's
    /// (which replace stdlib modules of the same name). Duplicates go to `diags`.
    fn modules(&self, diags: &mut Vec<Diagnostic>) -> HashMap<String, &ast::ModuleDef> {
        let mut modules = collect_modules(self.std_asts.iter().flat_map(|a| a.items.iter()), diags);
        modules.extend(collect_modules(self.ast.items.iter(), diags));
        modules
    }

    /// Checks and lowers scene `name` again with its knobs overridden by
    /// `knobs` (name, value as source text). Diagnostics point into the
    /// scene or into the override's text, added to the sources as a file
    /// named `--knob NAME`.
    fn lower_with_knobs(&self, name: &str, knobs: &[(String, String)]) -> Result<Function, PipelineError> {
        let scene = self
            .ast
            .items
            .iter()
            .find_map(|i| match i {
                ast::Item::Scene(s) if s.name.node == name => Some(s),
                _ => None,
            })
            .ok_or_else(|| PipelineError::Scene(format!("no scene `{name}`")))?;
        let mut sources = self.sources.clone();
        let mut diags = Vec::new();
        let mut overrides = Vec::new();
        for (knob, text) in knobs {
            let file = sources.add(format!("--knob {knob}"), text.clone());
            let (value, mut d) = syntax::parse_expr(text, file);
            diags.append(&mut d);
            if let Some(value) = value {
                overrides.push(KnobOverride { name: knob.clone(), value });
            }
        }
        let lowered =
            if diags.is_empty() { Checker::new(self.modules(&mut Vec::new())).lower_scene(scene, &overrides) } else { Err(diags) };
        lowered.map_err(|diagnostics| PipelineError::Compile(CompileError { diagnostics, sources }))
    }

    /// Names of the scenes, in source order.
    pub fn scene_names(&self) -> Vec<&str> {
        self.scenes.iter().map(|s| s.name.as_str()).collect()
    }

    /// The checked IR of scene `name`, or a description of what exists.
    pub fn scene_ir(&self, name: Option<&str>) -> Result<&Function, String> {
        match name {
            Some(n) => self.scenes.iter().find(|s| s.name == n).ok_or_else(|| {
                let names = self.scene_names();
                match crate::front::diagnostics::did_you_mean(n, names.iter().copied()) {
                    Some(s) => format!("no scene `{n}`; did you mean `{s}`?"),
                    None => format!("no scene `{n}`; scenes: {}", if names.is_empty() { "(none)".into() } else { names.join(", ") }),
                }
            }),
            None => match self.scenes.as_slice() {
                [one] => Ok(one),
                [] => Err("the file defines no scene; add `scene NAME { ... }`".into()),
                many => Err(format!(
                    "the file defines {} scenes ({}); choose one with --scene",
                    many.len(),
                    many.iter().map(|s| s.name.as_str()).collect::<Vec<_>>().join(", ")
                )),
            },
        }
    }

    /// Runs scene `name` through prune, adjoint and simplify.
    pub fn pipeline(&self, name: Option<&str>, opts: Options) -> Result<ScenePipeline, PipelineError> {
        let mut checked = self.scene_ir(name).map_err(PipelineError::Scene)?.clone();
        if !opts.knobs.is_empty() {
            checked = self.lower_with_knobs(&checked.name, &opts.knobs)?;
        }
        if let Some(m) = opts.math {
            checked.math = m;
        }
        if let Some(p) = opts.precision {
            checked.precision = p;
        }
        if let Some(m) = opts.multiband {
            checked.multiband = m;
        }
        if let Some(r) = opts.relative_binning {
            checked.relative_binning = r;
        }
        if let Some(keep) = &opts.outputs {
            if let Some(unknown) = keep.iter().find(|k| !checked.outputs.iter().any(|o| &o.name == *k)) {
                return Err(PipelineError::Scene(format!("scene `{}` has no output `{unknown}`", checked.name)));
            }
            checked.retain_outputs(|o| keep.contains(&o.name));
        }
        checked.freeze_params(&opts.frozen_params).map_err(PipelineError::Scene)?;
        run_passes(checked, verify_after_passes(&opts))
    }
}

/// Whether `GWML_VERIFY=1` asks for the IR to be verified after every
/// pass (read once; the only environment the compiler reads).
fn verify_requested_by_env() -> bool {
    static VERIFY: OnceLock<bool> = OnceLock::new();
    *VERIFY.get_or_init(|| std::env::var("GWML_VERIFY").is_ok_and(|v| v == "1"))
}

/// Whether passes are followed by the verifier: always in debug builds
/// (and so in every test), in release when [`Options::verify`] or
/// `GWML_VERIFY=1` asks.
fn verify_after_passes(opts: &Options) -> bool {
    cfg!(debug_assertions) || opts.verify || verify_requested_by_env()
}

/// An IR-to-IR pass, by name (the name is what `--stats` and an
/// internal error print).
type Pass = (&'static str, fn(&Function) -> Function);

/// The passes from the checked IR to what codegen compiles, in order.
/// Then [`finish`] stages the result and runs [`LATE_PASSES`] on each part.
const GRADIENT_PASSES: [Pass; 7] = [
    ("prune", passes::prune),
    ("relbin", passes::relbin),
    ("cutsum", passes::cutsum),
    ("multiband", passes::multiband),
    ("split_powers", passes::split_powers),
    ("adjoint", passes::adjoint),
    ("simplify", passes::simplify),
];

/// The passes of a forward-only kernel: as [`GRADIENT_PASSES`] without the adjoint.
/// It starts from [`ScenePipeline::pruned`], which is already multibanded;
/// then [`finish`].
const FORWARD_PASSES: [Pass; 2] = [("prune", passes::prune), ("simplify", passes::simplify)];

/// The passes after staging, on the main function and on the prelude.
const LATE_PASSES: [Pass; 2] = [("specialise", passes::specialise), ("rescale", passes::rescale)];

/// What one kernel runs: the per-call function and, when values computed
/// from the data alone were split off, the prelude that computes them.
#[derive(Clone, Debug)]
pub struct KernelIr {
    /// The whole computation in one function (what the interpreter runs
    /// and callers bind by name).
    pub whole: Function,
    /// Computes `main`'s cached inputs (`passes::stage`).
    pub prelude: Option<Function>,
    /// The per-call function: `whole` itself when nothing was split off.
    pub main: Function,
}

/// Runs [`LATE_PASSES`] on one function.
fn late(mut func: Function, verify: bool, times: &mut PassTimes) -> Result<Function, PipelineError> {
    for pass in LATE_PASSES {
        func = run_pass(pass, &func, verify, times)?;
    }
    Ok(func)
}

/// Stages a simplified function and runs [`LATE_PASSES`] on the whole
/// function and on each part.
fn finish(simplified: Function, verify: bool, times: &mut PassTimes) -> Result<KernelIr, PipelineError> {
    let t = Instant::now();
    let staged = passes::stage::split(&simplified);
    times.passes.push(("stage", t.elapsed()));
    let whole = late(simplified, verify, times)?;
    Ok(match staged {
        Some(s) => KernelIr { prelude: Some(late(s.prelude, verify, times)?), main: late(s.main, verify, times)?, whole },
        None => KernelIr { prelude: None, main: whole.clone(), whole },
    })
}

/// Times of the passes, and of the verifier after them.
#[derive(Default)]
struct PassTimes {
    passes: Vec<(&'static str, Duration)>,
    verify: Option<Duration>,
}

/// Runs one pass, timing it and, when `verify`, checking the IR it returns
/// (a failure is a compiler bug, reported as [`PipelineError::Internal`]).
fn run_pass((name, pass): Pass, input: &Function, verify: bool, times: &mut PassTimes) -> Result<Function, PipelineError> {
    let t = Instant::now();
    let output = pass(input);
    times.passes.push((name, t.elapsed()));
    if verify {
        let t = Instant::now();
        output.verify().map_err(|message| PipelineError::Internal { pass: name, message })?;
        *times.verify.get_or_insert(Duration::ZERO) += t.elapsed();
    }
    Ok(output)
}

/// Runs the gradient pipeline ([`GRADIENT_PASSES`]) on a checked function,
/// keeping the IR after pruning, after the adjoint and at the end.
pub fn run_passes(checked: Function, verify: bool) -> Result<ScenePipeline, PipelineError> {
    let mut times = PassTimes::default();
    let [prune, relbin, cutsum, multiband, split_powers, adjoint, simplify] = GRADIENT_PASSES;
    let pruned = run_pass(prune, &checked, verify, &mut times)?;
    let pruned = run_pass(relbin, &pruned, verify, &mut times)?;
    let pruned = run_pass(cutsum, &pruned, verify, &mut times)?;
    let pruned = run_pass(multiband, &pruned, verify, &mut times)?;
    let split = run_pass(split_powers, &pruned, verify, &mut times)?;
    let adjoint = run_pass(adjoint, &split, verify, &mut times)?;
    let simplified = run_pass(simplify, &adjoint, verify, &mut times)?;
    let kernel = finish(simplified, verify, &mut times)?;
    let optimized = kernel.whole.clone();
    let stats = Stats {
        checked_ops: checked.insts.len(),
        pruned_ops: pruned.insts.len(),
        adjoint_ops: adjoint.insts.len(),
        optimized_ops: optimized.insts.len(),
        times: times.passes.into_iter().chain(times.verify.map(|t| ("verify", t))).collect(),
    };
    Ok(ScenePipeline { checked, pruned, adjoint, optimized, kernel, stats, verify })
}

impl ScenePipeline {
    /// The IR of the forward-only kernel: the pruned IR without its
    /// gradients, through [`FORWARD_PASSES`]. A scene without gradients
    /// has it already, as its gradient kernel, which then computes the
    /// outputs alone: it is reused, so the tables of a long grid (most of
    /// what compiling the scan's whitening costs) are computed once.
    pub fn forward(&self) -> Result<KernelIr, PipelineError> {
        if self.pruned.grads.is_empty() && self.pruned.input_grads.is_empty() {
            return Ok(self.kernel.clone());
        }
        let mut func = self.pruned.clone();
        func.grads.clear();
        func.input_grads.clear();
        let mut times = PassTimes::default();
        for pass in FORWARD_PASSES {
            func = run_pass(pass, &func, self.verify, &mut times)?;
        }
        finish(func, self.verify, &mut times)
    }
}

/// The text of `func` as `--emit ir|adjoint` prints it: in mixed
/// precision, the values computed in f64 are marked (this runs the
/// precision analysis; plain `Display` runs nothing).
pub fn ir_text(func: &Function) -> String {
    func.marked(&passes::precision::wide_values(func)).to_string()
}

fn dedup(diags: &mut Vec<Diagnostic>) {
    let mut seen = std::collections::HashSet::new();
    diags.retain(|d| seen.insert((d.span, d.message.clone())));
}

fn load_imports(
    ast: &ast::SourceFileAst,
    sources: &mut SourceMap,
    loaded: &mut Vec<(String, ast::SourceFileAst)>,
    diags: &mut Vec<Diagnostic>,
) {
    let mut imported: HashMap<&str, Span> = HashMap::new();
    for item in &ast.items {
        let ast::Item::Use(u) = item else { continue };
        for n in &u.names {
            if let Some(prev) = imported.insert(n.node.as_str(), n.span) {
                diags.push(
                    Diagnostic::error(n.span, format!("`{}` is imported twice", n.node))
                        .with_secondary(prev, "first imported here")
                        .with_help("import each name once"),
                );
            }
        }
        let path: Vec<&str> = u.path.iter().map(|p| p.node.as_str()).collect();
        if path.first() != Some(&"std") || path.len() != 2 {
            diags.push(Diagnostic::error(u.span, format!("cannot import from `{}`", path.join("::"))).with_help(format!(
                "imports name a standard library file: `use std::FILE::{{NAME}}`; files: {}",
                stdlib::FILES.iter().map(|f| f.0).collect::<Vec<_>>().join(", ")
            )));
            continue;
        }
        let name = path[1];
        let Some(text) = stdlib::source(name) else {
            let mut d = Diagnostic::error(u.path[1].span, format!("no standard library file `{name}`"));
            d = match crate::front::diagnostics::did_you_mean(name, stdlib::FILES.iter().map(|f| f.0)) {
                Some(s) => d.with_help(format!("did you mean `std::{s}`?")),
                None => d.with_help(format!("files: {}", stdlib::FILES.iter().map(|f| f.0).collect::<Vec<_>>().join(", "))),
            };
            diags.push(d);
            continue;
        };
        let display = format!("std::{name}");
        if !loaded.iter().any(|(n, _)| *n == display) {
            let id: FileId = sources.add(display.clone(), text);
            let (std_ast, mut d) = syntax::parse(text, id);
            diags.append(&mut d);
            loaded.push((display.clone(), std_ast.clone()));
            load_imports(&std_ast, sources, loaded, diags);
        }
        let std_ast = &loaded.iter().find(|(n, _)| *n == display).expect("just loaded").1;
        for n in &u.names {
            let exists = std_ast.items.iter().any(|i| matches!(i, ast::Item::Module(m) if m.name.node == n.node));
            if !exists {
                let names: Vec<&str> = std_ast
                    .items
                    .iter()
                    .filter_map(|i| if let ast::Item::Module(m) = i { Some(m.name.node.as_str()) } else { None })
                    .collect();
                let mut d = Diagnostic::error(n.span, format!("`std::{name}` has no module `{}`", n.node));
                d = match crate::front::diagnostics::did_you_mean(&n.node, names.iter().copied()) {
                    Some(s) => d.with_help(format!("did you mean `{s}`?")),
                    None => d.with_help(format!("it defines: {}", names.join(", "))),
                };
                diags.push(d);
            }
        }
    }
}
