//! Well-typed `.gw` programs generated from fuzz bytes: one scene with a
//! few dimensionless params, an optional frequency grid, a chain of `let`s
//! over real and complex scalars and arrays, an optional module, a real
//! scalar `loss` with its gradient, and array outputs. Every expression is
//! typed by construction (units stay dimensionless; arguments of `log`,
//! `sqrt` and divisions are kept positive), so a program that fails to
//! check is a bug in the checker or in this generator.

use libfuzzer_sys::arbitrary::Unstructured;

/// Real or complex, scalar or over the grid.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Ty {
    RealScalar,
    RealGrid,
    ComplexScalar,
    ComplexGrid,
}

impl Ty {
    fn real(self) -> Ty {
        match self {
            Ty::ComplexScalar => Ty::RealScalar,
            Ty::ComplexGrid => Ty::RealGrid,
            t => t,
        }
    }
    fn complex(self) -> Ty {
        match self {
            Ty::RealScalar => Ty::ComplexScalar,
            Ty::RealGrid => Ty::ComplexGrid,
            t => t,
        }
    }
    fn scalar(self) -> Ty {
        match self {
            Ty::RealGrid => Ty::RealScalar,
            Ty::ComplexGrid => Ty::ComplexScalar,
            t => t,
        }
    }
    fn is_grid(self) -> bool {
        matches!(self, Ty::RealGrid | Ty::ComplexGrid)
    }
}

/// A generated program and what the differential check needs to know.
pub struct Generated {
    pub text: String,
    /// No `abs`, `min`, `max` or `clamp`: finite differences apply.
    pub smooth: bool,
}

struct Gen<'a, 'b> {
    u: &'b mut Unstructured<'a>,
    /// Names usable as leaves, with their types.
    names: Vec<(String, Ty)>,
    grid: bool,
    /// A module `m0(a, b)` of two reals exists.
    module: bool,
    smooth: bool,
}

impl Gen<'_, '_> {
    fn pick(&mut self, n: usize) -> usize {
        if n <= 1 {
            return 0;
        }
        self.u.int_in_range(0..=n - 1).unwrap_or(0)
    }

    fn literal(&mut self) -> String {
        let k = self.u.int_in_range(-40i32..=40).unwrap_or(3);
        format!("{:.2}", k as f64 / 20.0 + 0.01)
    }

    fn leaf(&mut self, ty: Ty) -> String {
        let named: Vec<String> = self.names.iter().filter(|(_, t)| *t == ty).map(|(n, _)| n.clone()).collect();
        let k = self.pick(named.len() + 2);
        if k < named.len() {
            return named[k].clone();
        }
        match ty {
            Ty::RealScalar if k == named.len() && self.grid => "mean(x)".into(),
            Ty::RealScalar => self.literal(),
            Ty::RealGrid => {
                let s = self.leaf(Ty::RealScalar);
                if k == named.len() {
                    "x".into()
                } else {
                    format!("(x * {s})")
                }
            }
            Ty::ComplexScalar | Ty::ComplexGrid => {
                let a = self.leaf(ty.real());
                let b = self.leaf(ty.real());
                if k == named.len() {
                    format!("cis({a})")
                } else {
                    format!("complex({a}, {b})")
                }
            }
        }
    }

    /// A real operand for an operation whose result has type `ty`: of the
    /// same shape, or a scalar broadcast over the grid.
    fn operand(&mut self, ty: Ty, depth: u32) -> String {
        let t = if ty.is_grid() && self.pick(3) == 0 { ty.scalar() } else { ty };
        self.expr(t, depth)
    }

    fn expr(&mut self, ty: Ty, depth: u32) -> String {
        if depth == 0 || self.pick(4) == 0 {
            return self.leaf(ty);
        }
        let d = depth - 1;
        match ty {
            Ty::RealScalar | Ty::RealGrid => self.real_op(ty, d),
            Ty::ComplexScalar | Ty::ComplexGrid => self.complex_op(ty, d),
        }
    }

    fn real_op(&mut self, ty: Ty, d: u32) -> String {
        let a = self.expr(ty, d);
        match self.pick(24) {
            0 => format!("({a} + {})", self.operand(ty, d)),
            1 => format!("({a} - {})", self.operand(ty, d)),
            2 => format!("({a} * {})", self.operand(ty, d)),
            3 => format!("({a} / (1.5 + {b} * {b}))", b = self.operand(ty, d)),
            4 => format!("(-{a})"),
            5 => format!("sin({a})"),
            6 => format!("cos({a})"),
            7 => format!("tanh({a})"),
            8 => format!("exp(tanh({a}))"),
            9 => format!("log(1.25 + {a} * {a})"),
            10 => format!("sqrt(0.5 + {a} * {a})"),
            11 => format!("({a} ^ 2)"),
            12 => format!("(tanh({a}) ^ 3)"),
            13 => format!("atan2({a}, 1.0 + {b} * {b})", b = self.operand(ty, d)),
            14 => format!("cbrt(1.0 + {a} * {a})"),
            15 => format!("tan(0.5 * tanh({a}))"),
            16 => format!("re({})", self.expr(ty.complex(), d)),
            17 => format!("im({})", self.expr(ty.complex(), d)),
            18 => format!("abs2({})", self.expr(ty.complex(), d)),
            19 if self.module => format!("m0({a}, {})", self.operand(ty, d)),
            20 if ty == Ty::RealScalar && self.grid => format!("mean({})", self.expr(Ty::RealGrid, d)),
            21 if ty == Ty::RealScalar && self.grid => format!("(0.1 * sum({}))", self.expr(Ty::RealGrid, d)),
            22 => {
                self.smooth = false;
                match self.pick(4) {
                    0 => format!("abs({a})"),
                    1 => format!("min({a}, {})", self.operand(ty, d)),
                    2 => format!("max({a}, {})", self.operand(ty, d)),
                    _ => format!("clamp({a}, -1.0, 1.0)"),
                }
            }
            23 if ty == Ty::RealScalar && self.grid => {
                self.smooth = false;
                format!("max({})", self.expr(Ty::RealGrid, d))
            }
            _ => a,
        }
    }

    fn complex_op(&mut self, ty: Ty, d: u32) -> String {
        let a = self.expr(ty, d);
        match self.pick(9) {
            0 => format!("({a} + {})", self.expr(ty, d)),
            1 => format!("({a} - {})", self.expr(ty, d)),
            2 => format!("({a} * {})", self.expr(ty, d)),
            3 => format!("conj({a})"),
            4 => format!("({a} * {})", self.operand(ty.real(), d)),
            5 => format!("exp(complex(-({r} * {r}), {i}))", r = self.expr(ty.real(), d), i = self.operand(ty.real(), d)),
            6 => format!("cis({})", self.expr(ty.real(), d)),
            7 if ty == Ty::ComplexScalar && self.grid => format!("mean({})", self.expr(Ty::ComplexGrid, d)),
            _ => a,
        }
    }
}

/// A well-typed program from `u`.
pub fn program(u: &mut Unstructured) -> Generated {
    let mut g = Gen { u, names: Vec::new(), grid: false, module: false, smooth: true };
    let mut text = String::new();
    if g.pick(2) == 0 {
        // Over reals of any shape: its leaves are its two arguments.
        g.names = vec![("a".into(), Ty::RealScalar), ("b".into(), Ty::RealScalar)];
        let body = g.expr(Ty::RealScalar, 3);
        g.names.clear();
        // No grid yet, so the body has no reductions: it is elementwise.
        // `a * b` makes the result take its arguments' shape even where the
        // rest of the body ignores them.
        text += &format!("module m0(a, b) {{\n    {body} + 0.1 * a * b\n}}\n\n");
        g.module = true;
    }
    text += "scene fuzzed {\n";
    // One scene in four leaves f64 exact (value-only checks there).
    match g.pick(12) {
        0 => text += "    precision: f32\n",
        1 => text += "    precision: mixed\n",
        2 => text += "    math: fast\n",
        3 => text += "    multiband: 1e-2\n",
        _ => {}
    }
    if g.pick(3) > 0 {
        let from = 10 + g.pick(40);
        let n = 1 + g.pick(48);
        let step = [0.5, 1.0, 2.0][g.pick(3)];
        text += &format!("    grid f = frequencies(from: {from} Hz, to: {} Hz, step: {step} Hz)\n", from as f64 + step * n as f64);
        text += "    let x = f / 40 Hz\n";
        g.grid = true;
    }
    let n_params = 1 + g.pick(3);
    for i in 0..n_params {
        let v = g.literal();
        text += &format!("    param p{i} = {v}\n");
        g.names.push((format!("p{i}"), Ty::RealScalar));
    }
    let types: &[Ty] = if g.grid { &[Ty::RealScalar, Ty::RealGrid, Ty::ComplexScalar, Ty::ComplexGrid] } else { &[Ty::RealScalar, Ty::ComplexScalar] };
    let n_lets = g.pick(6);
    for i in 0..n_lets {
        let ty = types[g.pick(types.len())];
        let e = g.expr(ty, 3);
        text += &format!("    let l{i} = {e}\n");
        g.names.push((format!("l{i}"), ty));
    }
    let loss = g.expr(Ty::RealScalar, 4);
    text += &format!("    output loss = {loss}\n");
    let wrt: Vec<String> = (0..n_params).map(|i| format!("p{i}")).collect();
    text += &format!("    grad loss wrt [{}]\n", wrt.join(", "));
    if g.grid && g.pick(2) == 0 {
        let ty = [Ty::RealGrid, Ty::ComplexGrid][g.pick(2)];
        let e = g.expr(ty, 3);
        text += &format!("    output arr = {e}\n");
    }
    text += "}\n";
    Generated { text, smooth: g.smooth }
}
