//! `gwml repl`: an interactive session.
//!
//! The session is kept as source text: `use` lines, modules, and the
//! statements of one implicit scene (`grid`, `param`, `input`, `let`).
//! Every entry is checked by compiling that text with the new entry (and a
//! `let`, `param` or `knob` by evaluating it); an entry whose checking,
//! compilation or evaluation fails is reported and forgotten, so an error
//! never changes the session. Redefining a name replaces it, and since the
//! whole session is recompiled, its dependents follow.

use clap::Parser;
use gwml::compiler::ir::{Function, Precision, UnknownSetting};
use gwml::compiler::{Options, Program};
use gwml::{Error, Model, Value};
use rustyline::completion::{Completer, Pair};
use rustyline::error::ReadlineError;
use rustyline::highlight::Highlighter;
use rustyline::hint::Hinter;
use rustyline::validate::{ValidationContext, ValidationResult, Validator};
use rustyline::{Context, Editor, Helper};
use std::cell::RefCell;
use std::io::{BufRead, IsTerminal, Write};
use std::path::PathBuf;
use std::rc::Rc;
use std::time::Instant;

mod session;
use session::{Def, Generated, Loaded, Part, Session, SCENE, VALUE};

/// `:qscan STRAIN --gps T ...` parses its words as `gwml qscan` does.
#[derive(clap::Parser)]
struct QscanCommand {
    #[command(flatten)]
    args: crate::qscan::QscanArgs,
}

/// Commands, for `:help` and completion.
const COMMANDS: &[(&str, &str)] = &[
    (":grad", ":grad EXPR wrt NAME[, NAME...]   value and gradient of a real scalar"),
    (":type", ":type EXPR                       type, shape and unit"),
    (":ir", ":ir EXPR                         the IR of an expression"),
    (":adjoint", ":adjoint EXPR wrt NAME[, ...]    forward and adjoint IR after optimisation"),
    (":clif", ":clif EXPR                       the Cranelift IR of its kernel"),
    (":time", ":time EXPR [wrt NAME, ...]        median time of one evaluation (with the gradient)"),
    (":load", ":load FILE                       modules and scenes of a .gw file"),
    (":run", ":run SCENE [NAME=VALUE ...]      run a loaded scene"),
    (":save", ":save FILE                       write the session as a .gw file"),
    (":plot", ":plot EXPR to FILE.png              line plot of an array against its grid"),
    (
        ":qscan",
        ":qscan EXPR [to FILE.png]          Q-transform of an array over a time grid (s)\n  \
         :qscan STRAIN --gps T [--out Q.png] Q-scans of a strain file, as `gwml qscan`",
    ),
    (":precision", ":precision f64|f32|mixed         working precision"),
    (":defs", ":defs                            list the session's definitions"),
    (":undef", ":undef NAME                      forget a definition nothing else uses"),
    (":reset", ":reset                           forget every definition and loaded file"),
    (":help", ":help                            this list"),
    (":quit", ":quit                            leave (or Ctrl-D)"),
];

/// Runs the REPL on a terminal, or line by line on piped input.
/// Returns the number of entries that failed.
pub fn run() -> usize {
    let names = Rc::new(RefCell::new(Vec::new()));
    let mut repl = Repl { session: Session::default(), names: names.clone(), color: std::io::stderr().is_terminal() };
    if std::io::stdin().is_terminal() {
        repl.interactive(names)
    } else {
        repl.piped()
    }
}

struct Repl {
    session: Session,
    names: Rc<RefCell<Vec<String>>>,
    color: bool,
}

/// Completion of names and commands; Enter continues a line while braces are open.
struct ReplHelper {
    names: Rc<RefCell<Vec<String>>>,
}

impl Completer for ReplHelper {
    type Candidate = Pair;
    fn complete(&self, line: &str, pos: usize, _: &Context<'_>) -> rustyline::Result<(usize, Vec<Pair>)> {
        let start = line[..pos].rfind(|c: char| !(c.is_alphanumeric() || c == '_' || c == ':')).map(|i| i + 1).unwrap_or(0);
        let pairs = completions(&line[start..pos], start == 0, &self.names.borrow())
            .into_iter()
            .map(|c| Pair { display: c.clone(), replacement: c })
            .collect();
        Ok((start, pairs))
    }
}

/// The names, builtins, constants, units, standard-library modules and
/// learned components, keywords and (at the start of a line) commands that
/// begin with `word`, sorted.
fn completions(word: &str, line_start: bool, session_names: &[String]) -> Vec<String> {
    if word.is_empty() {
        return Vec::new();
    }
    let mut cands: Vec<String> = session_names.to_vec();
    cands.extend(gwml::compiler::check::BUILTINS.iter().map(|b| b.0.to_string()));
    cands.extend(gwml::compiler::check::CONSTANTS.iter().map(|c| c.name.to_string()));
    cands.extend(gwml::compiler::front::units::UNITS.iter().map(|u| u.name.to_string()));
    for (file, text) in gwml::compiler::front::stdlib::FILES {
        cands.push(format!("std::{file}"));
        cands.extend(
            text.lines()
                .filter_map(|l| l.strip_prefix("module ").or_else(|| l.strip_prefix("learned ")))
                .map(|rest| rest.chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect::<String>()),
        );
    }
    cands.extend(
        ["let", "param", "knob", "grid", "input", "module", "learned", "weight", "use", "wrt", "frequencies", "times", "index"]
            .iter()
            .map(|s| s.to_string()),
    );
    if line_start {
        cands.extend(COMMANDS.iter().map(|c| c.0.to_string()));
    }
    cands.retain(|c| c.starts_with(word));
    cands.sort();
    cands.dedup();
    cands
}

impl Hinter for ReplHelper {
    type Hint = String;
}
impl Highlighter for ReplHelper {}
impl Validator for ReplHelper {
    fn validate(&self, ctx: &mut ValidationContext<'_>) -> rustyline::Result<ValidationResult> {
        Ok(if open_braces(ctx.input()) > 0 { ValidationResult::Incomplete } else { ValidationResult::Valid(None) })
    }
}
impl Helper for ReplHelper {}

/// Unclosed `{`, `(` and `[` outside comments.
fn open_braces(text: &str) -> i64 {
    let mut depth = 0i64;
    for line in text.lines() {
        let code = line.split("//").next().unwrap_or("");
        for c in code.chars() {
            match c {
                '{' | '(' | '[' => depth += 1,
                '}' | ')' | ']' => depth -= 1,
                _ => {}
            }
        }
    }
    depth
}

fn history_path() -> Option<PathBuf> {
    let base = std::env::var_os("XDG_DATA_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".local/share")))?;
    let dir = base.join("gwml");
    std::fs::create_dir_all(&dir).ok()?;
    Some(dir.join("history"))
}

impl Repl {
    fn interactive(&mut self, names: Rc<RefCell<Vec<String>>>) -> usize {
        let Ok(mut rl) = Editor::<ReplHelper, rustyline::history::DefaultHistory>::new() else {
            eprintln!("error: cannot open the terminal for line editing; reading standard input instead");
            return self.piped();
        };
        rl.set_helper(Some(ReplHelper { names }));
        let history = history_path();
        if let Some(h) = &history {
            let _ = rl.load_history(h);
        }
        println!("gwml {} — :help for commands, Ctrl-D to leave", env!("CARGO_PKG_VERSION"));
        let mut failures = 0;
        loop {
            match rl.readline("gw> ") {
                Ok(line) => {
                    if line.trim().is_empty() {
                        continue;
                    }
                    let _ = rl.add_history_entry(line.as_str());
                    match self.entry(&line) {
                        Ok(true) => {}
                        Ok(false) => break,
                        Err(msg) => {
                            failures += 1;
                            eprint!("{msg}");
                        }
                    }
                }
                Err(ReadlineError::Interrupted) => continue,
                Err(_) => break,
            }
        }
        if let Some(h) = &history {
            let _ = rl.save_history(h);
        }
        failures
    }

    fn piped(&mut self) -> usize {
        let stdin = std::io::stdin();
        let mut failures = 0;
        let mut buffer = String::new();
        for line in stdin.lock().lines() {
            let Ok(line) = line else { break };
            if buffer.is_empty() && line.trim().is_empty() {
                continue;
            }
            buffer += &line;
            buffer += "\n";
            if open_braces(&buffer) > 0 {
                continue;
            }
            let entry = std::mem::take(&mut buffer);
            println!("gw> {}", entry.trim_end().replace('\n', "\n... "));
            match self.entry(&entry) {
                Ok(true) => {}
                Ok(false) => break,
                Err(msg) => {
                    failures += 1;
                    // Errors go to stdout too, so a transcript reads in order.
                    print!("{msg}");
                }
            }
            let _ = std::io::stdout().flush();
        }
        if !buffer.trim().is_empty() {
            println!("error: input ended inside an unclosed block");
            failures += 1;
        }
        failures
    }

    /// Handles one entry. `Ok(false)` means quit; `Err` holds the rendered error.
    fn entry(&mut self, text: &str) -> Result<bool, String> {
        let t = text.trim();
        if let Some(cmd) = t.strip_prefix(':') {
            return self.command(cmd, t);
        }
        let first = t.split_whitespace().next().unwrap_or("");
        let name_after = |kw: &str| -> Option<String> {
            let rest = t.strip_prefix(kw)?.trim_start();
            let n: String = rest.chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect();
            (!n.is_empty()).then_some(n)
        };
        let def = match first {
            "use" => Some(Def::Use(t.to_string())),
            // `learned` components are module-like definitions (issue 4 adds them to the language).
            "module" | "learned" => name_after(first).map(|n| Def::Module(n, t.to_string())),
            "let" | "param" | "knob" | "grid" | "input" => name_after(first).map(|n| Def::Stmt(n, t.to_string())),
            _ => None,
        };
        if let Some(def) = def {
            self.compile(&self.session.source(Some(&def), t, &[]))?;
            let shown = match &def {
                Def::Stmt(n, _) if ["let", "param", "knob"].contains(&first) => Some(n.clone()),
                _ => None,
            };
            // A value is evaluated before the definition is kept, so one that
            // cannot be evaluated changes nothing.
            let message = match &shown {
                Some(n) => format!("{n} = {}", self.evaluate_in(Some(&def), t, n)?),
                None => "ok".to_string(),
            };
            self.session.commit(def);
            *self.names.borrow_mut() = self.session.names();
            println!("{message}");
            return Ok(true);
        }
        let v = self.evaluate_in(None, t, t)?;
        println!("{v}");
        Ok(true)
    }

    fn render(&self, e: Error) -> String {
        match e {
            Error::Compile(c) => c.render(self.color),
            other => format!("error: {other}\n"),
        }
    }

    /// Compiles `program`; diagnostics point at what was typed.
    fn compile(&self, program: &Generated) -> Result<Model, String> {
        Model::from_source("<repl>", &program.text).map_err(|e| self.render_in(program, e))
    }

    fn render_in(&self, program: &Generated, e: Error) -> String {
        match e {
            Error::Compile(c) => program.remap(c).render(self.color),
            other => self.render(other),
        }
    }

    /// The session's scene with an output `__value` = `expr` (part of the
    /// entry `typed`) and `extra` statements.
    fn scene(&self, typed: &str, expr: &str, extra: &[Part]) -> Result<gwml::Scene, String> {
        let mut parts = vec![Part::Glue(format!("    output {VALUE} =\n")), Part::Typed(expr)];
        parts.extend(extra.iter().cloned());
        self.scene_in(None, typed, &parts)
    }

    /// The session's scene with `new` defined and `extra` statements.
    fn scene_in(&self, new: Option<&Def>, typed: &str, extra: &[Part]) -> Result<gwml::Scene, String> {
        let program = self.session.source(new, typed, extra);
        let model = self.compile(&program)?;
        model
            .scene_with(Some(SCENE), Options { precision: self.session.precision, ..Default::default() })
            .map_err(|e| self.render_in(&program, e))
    }

    /// Value of `expr` (part of the entry `typed`) in the session with
    /// `new` defined, formatted.
    fn evaluate_in(&self, new: Option<&Def>, typed: &str, expr: &str) -> Result<String, String> {
        let scene = self.scene_in(new, typed, &[Part::Glue(format!("    output {VALUE} =\n")), Part::Typed(expr)])?;
        // Run-time errors name the generated output: name what was typed.
        let typed = |e: Error| self.render(e).replace(&format!("output `{VALUE}`"), &format!("`{}`", expr.trim()));
        let out = scene.bind().forward().map_err(typed)?;
        let f = scene.ir();
        let unit = &f.outputs[0].unit;
        Ok(format_value(out.value(VALUE).map_err(|e| self.render(e))?, f, unit))
    }

    /// Handles `:cmd`, typed as `typed`.
    fn command(&mut self, cmd: &str, typed: &str) -> Result<bool, String> {
        let (name, rest) = cmd.split_once(char::is_whitespace).map(|(a, b)| (a, b.trim())).unwrap_or((cmd.trim(), ""));
        match name {
            "q" | "quit" | "exit" => return Ok(false),
            "help" | "h" => {
                for (_, help) in COMMANDS {
                    println!("  {help}");
                }
                println!("  Definitions: let, param, grid, input, module, use. Anything else is evaluated.");
            }
            "grad" | "adjoint" => {
                let (expr, wrt) = split_wrt(rest).ok_or_else(|| format!("error: usage: :{name} EXPR wrt NAME[, NAME...]\n"))?;
                let scene =
                    self.scene(typed, expr, &[Part::Glue(format!("\n    grad {VALUE} wrt [")), Part::Typed(wrt), Part::Glue("]".into())])?;
                if name == "adjoint" {
                    print!("{}", gwml::compiler::driver::ir_text(&scene.pipeline.optimized));
                    return Ok(true);
                }
                let out = scene.bind().value_and_grad().map_err(|e| self.render(e))?;
                let f = scene.ir();
                println!("{}", format_value(out.value(VALUE).map_err(|e| self.render(e))?, f, &f.outputs[0].unit));
                for (_, p, g) in &out.grads {
                    let unit = f.params.iter().find(|q| &q.name == p).map(|q| q.unit.as_str()).unwrap_or("1");
                    println!("  d/d{p} = {g}{}", if unit == "1" { String::new() } else { format!(" per {unit}") });
                }
            }
            "type" => {
                let scene = self.scene(typed, rest, &[])?;
                let f = scene.ir();
                let o = &f.outputs[0];
                println!("{} [{}]", f.fmt_ty(f.ty(o.value)), o.unit);
            }
            "ir" => print!("{}", gwml::compiler::driver::ir_text(&self.scene(typed, rest, &[])?.pipeline.pruned)),
            "clif" => print!("{}", self.scene(typed, rest, &[])?.forward_kernel().clif),
            "time" => {
                // `:time EXPR wrt NAME, ...` times the value and its gradient.
                let (expr, wrt) = match split_wrt(rest) {
                    Some((e, w)) => (e, Some(w)),
                    None => (rest, None),
                };
                let grad = match wrt {
                    Some(w) => vec![Part::Glue(format!("\n    grad {VALUE} wrt [")), Part::Typed(w), Part::Glue("]".into())],
                    None => Vec::new(),
                };
                let scene = self.scene(typed, expr, &grad)?;
                let mut run = scene.bind();
                let once = |run: &mut gwml::Run| if wrt.is_some() { run.value_and_grad() } else { run.forward() }.map(|_| ());
                once(&mut run).map_err(|e| self.render(e))?;
                let mut times: Vec<f64> = Vec::new();
                let start = Instant::now();
                while times.len() < 5 || (start.elapsed().as_secs_f64() < 0.5 && times.len() < 10_000) {
                    let t = Instant::now();
                    once(&mut run).map_err(|e| self.render(e))?;
                    times.push(t.elapsed().as_secs_f64());
                }
                times.sort_by(f64::total_cmp);
                let what = if wrt.is_some() { "value and gradient" } else { "value" };
                println!("median {} over {} runs ({what})", fmt_time(times[times.len() / 2]), times.len());
            }
            "load" => {
                let text = std::fs::read_to_string(rest).map_err(|e| format!("error: cannot read {rest}: {e}\n"))?;
                let program = Program::parse(rest, &text).map_err(|e| e.render(self.color))?;
                self.session.loaded.retain(|l| l.path != rest);
                self.session.loaded.push(Loaded::new(rest, text, &program));
                if let Err(e) = self.compile(&self.session.full_source()) {
                    self.session.loaded.pop();
                    return Err(e);
                }
                let scenes = program.scene_names();
                println!("loaded {rest}: scenes {}", if scenes.is_empty() { "(none)".into() } else { scenes.join(", ") });
            }
            "run" => {
                let mut parts = rest.split_whitespace();
                let scene_name = parts.next().ok_or("error: usage: :run SCENE [NAME=VALUE ...]\n")?;
                let model = self.compile(&self.session.full_source())?;
                let scene = model
                    .scene_with(Some(scene_name), Options { precision: self.session.precision, ..Default::default() })
                    .map_err(|e| self.render(e))?;
                let mut run = scene.bind();
                for kv in split_assignments(parts) {
                    let (k, v) = kv.split_once('=').ok_or_else(|| format!("error: expected NAME=VALUE, got `{kv}`\n"))?;
                    run.param_quantity(k.trim(), v).map_err(|e| self.render(e))?;
                }
                let has_grads = scene.ir().has_gradients();
                let out = if has_grads { run.value_and_grad() } else { run.forward() }.map_err(|e| self.render(e))?;
                let f = scene.ir();
                for ((n, v), o) in out.values.iter().zip(&f.outputs) {
                    println!("{n} = {}", format_value(v, f, &o.unit));
                }
                for (o, p, g) in &out.grads {
                    println!("  d{o}/d{p} = {g}");
                }
            }
            "save" => {
                // Settings go with the definitions: `:precision` becomes the scene's.
                let precision = self.session.precision.map(|p| format!("\n    precision: {p}")).unwrap_or_default();
                let src = self.session.full_source().text.replace(&format!("scene {SCENE} {{"), &format!("scene session {{{precision}"));
                Program::parse(rest, &src).map_err(|e| e.render(self.color))?;
                std::fs::write(rest, src).map_err(|e| format!("error: cannot write {rest}: {e}\n"))?;
                println!("saved {rest}");
            }
            "plot" => {
                let (expr, file) = rest.rsplit_once(" to ").ok_or("error: usage: :plot EXPR to FILE.png\n")?;
                let scene = self.scene(typed, expr, &[])?;
                let out = scene.bind().forward().map_err(|e| self.render(e))?;
                let f = scene.ir();
                let o = &f.outputs[0];
                let ys: Vec<f64> = match out.value(VALUE).map_err(|e| self.render(e))? {
                    Value::RealArray(a) => a.clone(),
                    Value::ComplexArray(a) => a.iter().map(|z| z.norm()).collect(),
                    _ => return Err("error: :plot needs an array (a value over a grid)\n".into()),
                };
                let gwml::compiler::ir::Shape::Grid(g) = f.ty(o.value).shape else { unreachable!("arrays live on grids") };
                let grid = f.grid(g);
                let xs: Vec<f64> = (0..grid.len).map(|i| grid.start + i as f64 * grid.step).collect();
                let y_label = if o.unit == "1" { expr.trim().to_string() } else { format!("{} [{}]", expr.trim(), o.unit) };
                gwml_lab::plot::line_plot(
                    std::path::Path::new(file.trim()),
                    expr.trim(),
                    &format!("{} [{}]", grid.name, grid.unit),
                    &y_label,
                    &xs,
                    &ys,
                )
                .map_err(|e| format!("error: {e}\n"))?;
                println!("wrote {}", file.trim());
            }
            "qscan" if rest.contains("--gps") => {
                let words = std::iter::once("qscan").chain(rest.split_whitespace());
                let args =
                    QscanCommand::try_parse_from(words).map_err(|e| format!("error: {}\n", e.to_string().trim_start_matches("error: ")))?;
                crate::qscan::qscan(args.args).map_err(|e| format!("{e}\n"))?;
            }
            "qscan" => {
                let (expr, file) = match rest.rsplit_once(" to ") {
                    Some((e, f)) => (e, Some(std::path::Path::new(f.trim()))),
                    None => (rest, None),
                };
                let scene = self.scene(typed, expr, &[])?;
                let out = scene.bind().forward().map_err(|e| self.render(e))?;
                let f = scene.ir();
                let o = &f.outputs[0];
                let (Value::RealArray(x), gwml::compiler::ir::Shape::Grid(g)) =
                    (out.value(VALUE).map_err(|e| self.render(e))?, f.ty(o.value).shape)
                else {
                    return Err("error: :qscan needs a real array over a time grid\n".into());
                };
                let grid = f.grid(g);
                if grid.unit != "s" {
                    return Err(format!("error: :qscan needs an array over a time grid; `{}` is in {}\n", grid.name, grid.unit));
                }
                let image = crate::qscan::q_image_of(x, 1.0 / grid.step, grid.start).map_err(|e| format!("{e}\n"))?;
                let p = image.peak;
                println!(
                    "Q {:.1}: loudest tile at {:.4} s, {:.1} Hz, normalised energy {:.4e} (tiles from {:.0} to {:.0} Hz)",
                    image.q,
                    p.time,
                    p.frequency,
                    p.energy,
                    image.frequencies[0],
                    image.frequencies[image.frequencies.len() - 1]
                );
                if p.energy > 1e6 {
                    println!("  (tile energies are normalised by each row's median, which noiseless data make tiny: add noise for a meaningful scale)");
                }
                if let Some(path) = file {
                    crate::qscan::plot_q_images(path, expr.trim(), 0.0, &[("Q-transform".to_string(), &image)])?;
                    println!("wrote {}", path.display());
                }
            }
            "precision" => {
                let precision: Precision = rest.parse().map_err(|e: UnknownSetting| format!("error: {e}; use {}\n", e.help))?;
                self.session.precision = Some(precision);
                println!("precision {rest}");
            }
            "reset" => {
                self.session = Session { precision: self.session.precision, ..Session::default() };
                *self.names.borrow_mut() = Vec::new();
                println!("session cleared (settings such as :precision kept)");
            }
            "undef" => {
                let name = rest.trim();
                let Some(smaller) = self.session.without(name) else {
                    let names = self.session.names();
                    let hint = gwml::compiler::front::diagnostics::did_you_mean(name, names.iter().map(|s| s.as_str()))
                        .map(|s| format!("; did you mean `{s}`?"))
                        .unwrap_or_default();
                    return Err(format!("error: the session defines no `{name}`{hint} (:defs lists them)\n"));
                };
                if let Err(e) = self.compile(&smaller.source(None, typed, &[])) {
                    return Err(format!("error: `{name}` is still used; forget what uses it first. Without it:\n{e}"));
                }
                self.session = smaller;
                *self.names.borrow_mut() = self.session.names();
                println!("forgot {name}");
            }
            "defs" => {
                for u in &self.session.uses {
                    println!("{u}");
                }
                for (_, s) in self.session.modules.iter().chain(&self.session.stmts) {
                    println!("{s}");
                }
            }
            other => {
                let names: Vec<&str> = COMMANDS.iter().map(|c| &c.0[1..]).collect();
                let hint = gwml::compiler::front::diagnostics::did_you_mean(other, names)
                    .map(|s| format!("; did you mean :{s}?"))
                    .unwrap_or_default();
                return Err(format!("error: unknown command :{other}{hint} (:help lists them)\n"));
            }
        }
        Ok(true)
    }
}

/// `EXPR wrt NAME, ...` (the names optionally in brackets) as the
/// expression and the names.
fn split_wrt(text: &str) -> Option<(&str, &str)> {
    let (expr, wrt) = text.rsplit_once(" wrt ")?;
    Some((expr, wrt.trim().trim_start_matches('[').trim_end_matches(']')))
}

/// `NAME=VALUE` assignments separated by spaces, where a value may carry a
/// unit after a space (`tc=2 ms mc=30 Msun`).
fn split_assignments<'a>(words: impl Iterator<Item = &'a str>) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for word in words {
        match out.last_mut() {
            Some(last) if !word.contains('=') => {
                last.push(' ');
                last.push_str(word);
            }
            _ => out.push(word.to_string()),
        }
    }
    out
}

fn fmt_time(s: f64) -> String {
    if s < 1e-6 {
        format!("{:.1} ns", s * 1e9)
    } else if s < 1e-3 {
        format!("{:.2} µs", s * 1e6)
    } else {
        format!("{:.3} ms", s * 1e3)
    }
}

fn unit_suffix(unit: &str) -> String {
    if unit == "1" {
        String::new()
    } else {
        format!(" [{unit}]")
    }
}

/// Scalars as numbers; arrays as type, length, ends and range.
fn format_value(v: &Value, f: &Function, unit: &str) -> String {
    let u = unit_suffix(unit);
    let grid = f.outputs.first().map(|o| format!("{} {}", f.fmt_ty(f.ty(o.value)), f.precision)).unwrap_or_default();
    match v {
        Value::Real(x) => format!("{x}{u}"),
        Value::Complex(z) => format!("{} {} {}i{u}", z.re, if z.im < 0.0 { '-' } else { '+' }, z.im.abs()),
        Value::RealArray(a) => {
            let (lo, hi) = a.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), x| (l.min(*x), h.max(*x)));
            let head: Vec<String> = a.iter().take(3).map(|x| format!("{x:.6e}")).collect();
            let tail: Vec<String> = a.iter().rev().take(2).rev().map(|x| format!("{x:.6e}")).collect();
            format!("{grid}, {} values{u}: {} … {}; min {lo:.6e}, max {hi:.6e}", a.len(), head.join(", "), tail.join(", "))
        }
        Value::ComplexArray(a) => {
            let c = |z: &num_complex::Complex64| format!("{:.4e}{:+.4e}i", z.re, z.im);
            let (lo, hi) = a.iter().map(|z| z.norm()).fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), x| (l.min(x), h.max(x)));
            let head: Vec<String> = a.iter().take(2).map(c).collect();
            let last = a.last().map(c).unwrap_or_default();
            format!("{grid}, {} values{u}: {} … {last}; |z| from {lo:.6e} to {hi:.6e}", a.len(), head.join(", "))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::completions;

    #[test]
    fn completion_offers_stdlib_modules_learned_components_and_session_names() {
        let session = vec!["my_chirp".to_string()];
        assert_eq!(completions("psd_corr", false, &session), vec!["psd_correction".to_string()]);
        assert!(completions("octave_b", false, &session).contains(&"octave_bump".to_string()));
        assert_eq!(completions("my_", false, &session), vec!["my_chirp".to_string()]);
        assert!(completions("std::constr", false, &session).contains(&"std::constrained".to_string()));
        assert!(completions("", false, &session).is_empty());
    }
}
