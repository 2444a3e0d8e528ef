//! Property tests: whatever the input, the compiler reports diagnostics or
//! produces IR, and never panics. Inputs are (a) random soups of the
//! language's tokens and (b) random character- and token-level mutations of
//! valid programs. Each input goes through `Program::parse`, diagnostic
//! rendering, and, when it compiles, `pipeline` for every scene (which
//! verifies the IR after every pass in debug builds).

use gwml_compiler::check::CONSTANTS;
use gwml_compiler::front::source::FileId;
use gwml_compiler::front::syntax::ast::{BinOp, Expr, ExprKind, Item, SceneStmt, UnitExpr};
use gwml_compiler::front::syntax::{parse, print_ast};
use gwml_compiler::{front::units, Program};
use proptest::prelude::*;
use proptest::sample::{select, Index};

const CHIRP_FIT: &str = include_str!("../../examples/chirp_fit.gw");

/// Standard-library modules, two scenes, a `times` grid and a knob.
const STDLIB_SCENES: &str = "// Standard-library chirp, SNR and a times grid.
use std::chirp::{newtonian_chirp, chirp_time}
use std::detector::{snr, norm2}

module psd(f: Hz, floor: s = 1e-4 s) {
    let y = f / 150 Hz
    floor * (y ^ (-4.0) + 2.0 + 2.0 * y ^ 2.0)
}

scene snr_scan {
    precision: f32
    grid f = frequencies(from: 20 Hz, to: 256 Hz, step: 0.5 Hz)
    param mc: Msun = 12.0 in 1.0..50.0
    param dist: Mpc = 400.0 in 10.0..5000.0
    param tc: s = 0.0
    let h = newtonian_chirp(f, mc, dist, tc, 0.0)
    output rho = snr(h, psd(f), 0.5 Hz)
    output tm: s = chirp_time(mc)
    grad rho wrt [mc, dist]
}

scene ringdown {
    grid t = times(rate: 1024 Hz, duration: 0.25 s)
    param f0: Hz = 250.0 in 20.0..1000.0
    param tau: s = 0.004 in 0.0001..0.1
    let h = exp(-t / tau) * sin(2.0 * pi * f0 * t)
    output energy = sum(h * h) / 1024 Hz
    grad energy wrt [f0, tau]
}
";

/// Branches, selects, clamps and reductions.
const BRANCHES: &str = "// Branches, clamps and reductions.
module soft(x, k = 4.0) {
    let s = tanh(k * x)
    if x > 0.0 { s * x } else { -s * x / 2.0 }
}

scene shapes {
    grid f = frequencies(from: 1 Hz, to: 64 Hz, step: 1 Hz)
    param a = 0.5 in -1.0..1.0
    param b = 2.0
    param c = 0.1
    let u = f / 32 Hz - a
    let v = select(u < 0.0, cbrt(u), sqrt(abs(u)))
    let w = clamp(v * b, -1.0, 1.0) + min(u, c) - max(u * u, c)
    let ang = atan2(sin(b * u), cos(b * u) + 2.0)
    output peak = max(w + ang) + min(abs(w))
    output total = mean(soft(w, k: b) * exp(-u * u)) + log(1.0 + c * c) ^ 1.5
    grad total wrt [a, b]
    grad peak wrt [a, c]
}
";

/// Complex inputs with defaults, typed lets, named module arguments.
const COMPLEX_FIT: &str = "// Complex data, typed lets and module arguments by name.
module model(f: Hz, amp: s, t0: s, ph = 0.0) {
    let w: real[f] = 2.0 * pi * f * t0
    amp * cis(w + ph) / (1.0 + 0.5i * f / 100 Hz)
}

scene fit {
    grid f = frequencies(from: 10 Hz, to: 200 Hz, step: 2 Hz)
    input d: complex[f] s = model(f, 1e-2 s, 3 ms, ph: 0.2)
    input w: real[f] = 1.0 + f / 1 kHz
    param amp: s = 0.01
    param t0: ms = 2.0 in -10.0..10.0
    param ph = 0.0
    let r: complex[f] s = d - model(f, amp, t0, ph: ph)
    output chi2 = sum(abs2(r) / w) / (1 s * 1 s)
    output overlap = re(sum(d * conj(model(f, amp, t0)))) / (1 s * 1 s);
    grad chi2 wrt [amp, t0, ph]
    grad overlap wrt ph
}
";

const SOURCES: &[&str] = &[CHIRP_FIT, STDLIB_SCENES, BRANCHES, COMPLEX_FIT];

/// Every keyword and operator, and a selection of names, units and numbers.
const TOKENS: &[&str] = &[
    // Keywords.
    "use",
    "module",
    "scene",
    "let",
    "param",
    "input",
    "output",
    "grad",
    "wrt",
    "grid",
    "in",
    "if",
    "else",
    "real",
    "complex",
    // Operators and punctuation.
    "::",
    "..",
    "==",
    "!=",
    "<=",
    ">=",
    "->",
    "+",
    "-",
    "*",
    "/",
    "^",
    "<",
    ">",
    "=",
    ":",
    ",",
    ";",
    "(",
    ")",
    "[",
    "]",
    "{",
    "}",
    // Names: builtins, stdlib, scene-ish names, knobs, grid arguments.
    "x",
    "y",
    "f",
    "t",
    "d",
    "h",
    "mc",
    "tc",
    "phic",
    "loss",
    "sqrt",
    "cbrt",
    "exp",
    "log",
    "sin",
    "cos",
    "tan",
    "tanh",
    "atan2",
    "abs",
    "min",
    "max",
    "clamp",
    "re",
    "im",
    "conj",
    "abs2",
    "cis",
    "select",
    "sum",
    "mean",
    "frequencies",
    "times",
    "from",
    "to",
    "step",
    "rate",
    "duration",
    "std",
    "chirp",
    "detector",
    "inner",
    "snr",
    "newtonian_chirp",
    "precision",
    "knob",
    "f32",
    "f64",
    "pi",
    "MTSUN",
    "MRSUN",
    "C",
    "MPC_M",
    "MPC_S",
    // Units.
    "s",
    "ms",
    "Hz",
    "kHz",
    "Msun",
    "m",
    "km",
    "Mpc",
    "rad",
    // Numbers, imaginary literals, odd characters and comments.
    "0",
    "1",
    "2.0",
    "0.125",
    "1e-3",
    "3e8",
    "1e308",
    "2.5i",
    "0i",
    "-",
    "#",
    "@",
    "é",
    "//",
    "\n",
];

/// A small scene the token soup is spliced into, so that soups reach the checker.
const SKELETON_HEAD: &str =
    "scene s {\n  grid f = frequencies(from: 20 Hz, to: 30 Hz, step: 1 Hz)\n  param x = 1.0\n  input d: complex[f]\n";
const SKELETON_TAIL: &str = "\n  output loss = x\n  grad loss wrt [x]\n}\n";

/// The largest grid the property tests let the compiler build (an input
/// default is evaluated over its grid at compile time).
const MAX_POINTS: f64 = 2e5;

fn unit_scale(u: &UnitExpr) -> Option<f64> {
    match u {
        UnitExpr::One => Some(1.0),
        UnitExpr::Name(n) => units::unit(&n.node).map(|u| u.scale),
        UnitExpr::Mul(a, b) => Some(unit_scale(a)? * unit_scale(b)?),
        UnitExpr::Div(a, b) => Some(unit_scale(a)? / unit_scale(b)?),
        UnitExpr::Pow(a, n, d) => Some(unit_scale(a)?.powf(*n as f64 / *d as f64)),
    }
}

/// The value of a constant expression, roughly as the compiler sees it;
/// `None` when the compiler would reject it as a grid argument anyway.
fn const_value(e: &Expr) -> Option<f64> {
    match &e.node {
        ExprKind::Number(x, None) => Some(*x),
        ExprKind::Number(x, Some(u)) => Some(x * unit_scale(&u.node)?),
        ExprKind::Name(n) => CONSTANTS.iter().find(|c| c.name == n).map(|c| c.value),
        ExprKind::Neg(a) => Some(-const_value(a)?),
        ExprKind::Binary(op, a, b) => {
            let (a, b) = (const_value(a)?, const_value(b)?);
            match op {
                BinOp::Add => Some(a + b),
                BinOp::Sub => Some(a - b),
                BinOp::Mul => Some(a * b),
                BinOp::Div => Some(a / b),
                BinOp::Pow => Some(a.powf(b)),
                _ => None,
            }
        }
        _ => None,
    }
}

/// True if `src` declares a grid the compiler would accept with more than
/// `MAX_POINTS` points: compiling it is legitimate but slow and memory-hungry.
fn declares_huge_grid(src: &str) -> bool {
    let (ast, _) = parse(src, FileId(0));
    for item in &ast.items {
        let Item::Scene(scene) = item else { continue };
        for st in &scene.stmts {
            let SceneStmt::Grid { def, .. } = st else { continue };
            let ExprKind::Call { callee, args } = &def.node else { continue };
            let arg =
                |name: &str| args.iter().find(|a| a.name.as_ref().is_some_and(|n| n.node == name)).and_then(|a| const_value(&a.value));
            let points = match callee.node.as_str() {
                "frequencies" => match (arg("from"), arg("to"), arg("step")) {
                    (Some(a), Some(b), Some(s)) => (b - a) / s,
                    _ => continue,
                },
                "times" => match (arg("rate"), arg("duration")) {
                    (Some(r), Some(d)) => r * d,
                    _ => continue,
                },
                _ => continue,
            };
            // NaN (e.g. 0/0) would be rejected by the compiler; anything else big is skipped.
            if points.is_nan() {
                continue;
            }
            if points.abs() > MAX_POINTS {
                return true;
            }
        }
    }
    false
}

/// Runs `src` through everything the compiler does before code generation.
/// Returns whether it compiled.
fn compile_everything(src: &str) -> bool {
    // The parser alone, and the AST printer, on whatever it recovered.
    let (ast, _) = parse(src, FileId(0));
    let _ = print_ast(&ast);
    if declares_huge_grid(src) {
        return false;
    }
    match Program::parse("fuzz.gw", src) {
        Ok(program) => {
            let names: Vec<String> = program.scene_names().iter().map(|s| s.to_string()).collect();
            for name in &names {
                let pl = program.pipeline(Some(name), Default::default()).unwrap_or_else(|e| panic!("pipeline({name}): {e}"));
                for (stage, f) in [("checked", &pl.checked), ("pruned", &pl.pruned), ("adjoint", &pl.adjoint), ("optimized", &pl.optimized)]
                {
                    if let Err(e) = f.verify() {
                        panic!("invalid {stage} IR for scene {name}: {e}\n{f}");
                    }
                    let _ = f.to_string();
                }
                assert!(pl.optimized.grads.iter().all(|g| g.value.is_some()), "a gradient was not computed");
            }
            let _ = program.pipeline(None, Default::default());
            let _ = program.pipeline(Some("no such scene"), Default::default());
            true
        }
        Err(e) => {
            assert!(!e.diagnostics.is_empty(), "a compile error without diagnostics");
            let text = e.render(false);
            assert!(text.contains("Error"), "rendered diagnostics: {text}");
            let _ = e.render(true);
            false
        }
    }
}

/// A source as tokens for token-level mutation: runs of name characters,
/// runs of whitespace, and single other characters.
fn tokenize(src: &str) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    let kind = |c: char| {
        if c.is_alphanumeric() || c == '_' || c == '.' {
            0
        } else if c.is_whitespace() {
            1
        } else {
            2
        }
    };
    for c in src.chars() {
        match out.last_mut() {
            Some(last) if kind(c) != 2 && last.chars().next().map(kind) == Some(kind(c)) => last.push(c),
            _ => out.push(c.to_string()),
        }
    }
    out
}

/// Characters inserted by character-level mutations. No letters: inserting
/// `k` before `Hz` would turn a grid into millions of points.
const INSERT_CHARS: &[char] =
    &['(', ')', '{', '}', '[', ']', '+', '-', '*', '/', '^', '<', '>', '=', ':', ',', '.', ';', '0', '1', ' ', '\n', 'i', '#', '_', 'é'];

/// One mutation: `(kind, at, what)`.
type Mutation = (u8, Index, Index);

fn mutate(src: &str, mutations: &[Mutation]) -> String {
    let mut chars: Vec<char> = src.chars().collect();
    for (kind, at, what) in mutations {
        if kind & 4 == 0 {
            // Character level.
            if chars.is_empty() {
                chars.push(INSERT_CHARS[what.index(INSERT_CHARS.len())]);
                continue;
            }
            let i = at.index(chars.len());
            match kind & 3 {
                0 => {
                    chars.remove(i);
                }
                1 => chars.insert(i, chars[i]),
                2 => {
                    let j = (i + 1).min(chars.len() - 1);
                    chars.swap(i, j);
                }
                _ => chars.insert(i, INSERT_CHARS[what.index(INSERT_CHARS.len())]),
            }
        } else {
            // Token level.
            let mut toks = tokenize(&chars.iter().collect::<String>());
            if toks.is_empty() {
                toks.push(TOKENS[what.index(TOKENS.len())].to_string());
            } else {
                let i = at.index(toks.len());
                match kind & 3 {
                    0 => {
                        toks.remove(i);
                    }
                    1 => {
                        let t = toks[i].clone();
                        toks.insert(i, t);
                    }
                    2 => {
                        // With the next token that is not whitespace.
                        if let Some(j) = (i + 1..toks.len()).find(|&j| !toks[j].trim().is_empty()) {
                            toks.swap(i, j);
                        }
                    }
                    _ => toks.insert(i, format!(" {} ", TOKENS[what.index(TOKENS.len())])),
                }
            }
            chars = toks.concat().chars().collect();
        }
    }
    chars.into_iter().collect()
}

fn soup() -> impl Strategy<Value = String> {
    prop::collection::vec((select(TOKENS), select(&["", " ", " ", "\n"][..])), 0..80)
        .prop_map(|ts| ts.into_iter().map(|(t, sep)| format!("{t}{sep}")).collect())
}

#[test]
fn the_seed_sources_compile() {
    for src in SOURCES {
        assert!(compile_everything(src), "a seed source does not compile:\n{src}");
        assert!(!declares_huge_grid(src));
    }
    assert_eq!(mutate("ab", &[]), "ab");
}

#[test]
fn huge_grids_are_recognised() {
    assert!(declares_huge_grid("scene s { grid f = frequencies(from: 20 Hz, to: 1024 kHz, step: 0.125 Hz) }"));
    assert!(declares_huge_grid("scene s { grid t = times(rate: 1e9 Hz, duration: 1 s) }"));
    assert!(!declares_huge_grid(CHIRP_FIT));
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn token_soup_never_panics(src in soup()) {
        compile_everything(&src);
    }

    #[test]
    fn token_soup_inside_a_scene_never_panics(body in soup()) {
        compile_everything(&format!("{SKELETON_HEAD}{body}{SKELETON_TAIL}"));
    }

    #[test]
    fn mutated_programs_never_panic(
        which in 0..SOURCES.len(),
        mutations in prop::collection::vec((0u8..8, any::<Index>(), any::<Index>()), 1..3),
    ) {
        compile_everything(&mutate(SOURCES[which], &mutations));
    }

    #[test]
    fn heavily_mutated_programs_never_panic(
        which in 0..SOURCES.len(),
        mutations in prop::collection::vec((0u8..8, any::<Index>(), any::<Index>()), 5..40),
    ) {
        compile_everything(&mutate(SOURCES[which], &mutations));
    }
}
