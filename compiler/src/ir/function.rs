//! A scene lowered to IR ([`Function`]): grids, params, inputs,
//! instructions, outputs and requested gradients.

use super::ops::*;
use super::settings::{MathMode, Multiband, Precision, RelativeBinning};
use super::types::*;

/// A uniform grid: `len` points `start + i * step` (base units). Grids of
/// tensors (the layers of `learned` components) are index grids (start 0,
/// step 1) whose points are the row-major elements of an array of `dims`.
#[derive(Clone, Debug, PartialEq)]
pub struct Grid {
    /// Name in the scene.
    pub name: String,
    /// First coordinate.
    pub start: f64,
    /// Spacing.
    pub step: f64,
    /// Number of points.
    pub len: usize,
    /// Unit of the coordinates, for display.
    pub unit: String,
    /// Tensor dimensions (product `len`); `[len]` for a physical grid.
    pub dims: Vec<usize>,
}

impl Grid {
    /// An index grid of `len` points (start 0, step 1, no unit).
    pub fn index(name: String, len: usize) -> Grid {
        Grid { name, start: 0.0, step: 1.0, len, unit: String::new(), dims: vec![len] }
    }
}

/// A scalar parameter of the scene.
#[derive(Clone, Debug, PartialEq)]
pub struct ParamInfo {
    /// Name.
    pub name: String,
    /// Default value in the declared unit.
    pub default: Option<f64>,
    /// Bounds in the declared unit.
    pub bounds: Option<(f64, f64)>,
    /// Base units per declared unit (values are multiplied by it on the way in).
    pub scale: f64,
    /// Declared unit, for display.
    pub unit: String,
    /// Its dimension in base units as the checker prints it (`s`, `Hz`,
    /// `Msun`, `1`), to convert values given in other units.
    pub dim: String,
}

/// Run-time data of the scene.
#[derive(Clone, Debug, PartialEq)]
pub struct InputInfo {
    /// Name.
    pub name: String,
    /// Type (element kind and shape).
    pub ty: Ty,
    /// Base units per declared unit.
    pub scale: f64,
    /// Declared unit, for display.
    pub unit: String,
    /// Data used when none is bound (base units), from the input's default.
    pub default: Option<Vec<num_complex::Complex64>>,
    /// What the input is for.
    pub role: InputRole,
}

impl InputInfo {
    /// Whether it is a weight tensor (trainable).
    pub fn is_weight(&self) -> bool {
        self.role == InputRole::Weight
    }
}

/// What a scene input is for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum InputRole {
    /// Data the caller binds (or its default).
    Data,
    /// A weight tensor of a `learned` component (initialised in `default`),
    /// which `grad ... wrt` may name.
    Weight,
    /// The mask of a `dropout(x, rate)`: all ones by default (evaluation);
    /// a trainer binds a fresh mask per example, each element 0 with
    /// probability `rate` and 1/(1 − rate) otherwise.
    DropoutMask(f64),
    /// The draws of a `randn(...)`: zeros by default (the mean); a trainer
    /// binds fresh standard normal values per example and step, a sampler
    /// per draw.
    Noise,
    /// A value computed from the data alone by the scene's prelude (see
    /// `passes::stage`), which the runtime binds: not for callers.
    Cached,
}

/// A real array over a grid computed at compile time.
#[derive(Clone, Debug, PartialEq)]
pub struct Table {
    /// The grid it lives on.
    pub grid: GridId,
    /// One value per grid point.
    pub data: Vec<f64>,
}

/// A coarse subset of a grid's points for multibanding
/// (`passes::multiband`): the coarse grid is an index grid of
/// `nodes.len()` points, point `j` standing for fine point `nodes[j]`.
#[derive(Clone, Debug, PartialEq)]
pub struct Banding {
    /// The grid the fine values live on.
    pub fine: GridId,
    /// The coarse grid.
    pub coarse: GridId,
    /// Fine indices of the nodes, increasing, from 0 to the last point.
    pub nodes: Vec<u32>,
    /// For multibanding, the largest error of the interpolated phase at
    /// the scene's defaults; for relative binning, the bound on how much
    /// any waveform's phase can differ from the fiducial's across one band
    /// (Zackay, Dai & Venumadhav 2018). In radians, for `--emit ir`.
    pub error: f64,
    /// Which pass made it.
    pub purpose: BandPurpose,
}

/// What a [`Banding`] is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BandPurpose {
    /// `passes::multiband`: a phase interpolated between the nodes.
    Multiband,
    /// `passes::relbin`: the edges of the bins; a waveform's ratio to the
    /// fiducial interpolated between them, likelihood sums from summary data.
    RelativeBinning,
    /// `passes::relbin`: the midpoint of each bin of the banding before it
    /// (and its last point), where the ratio is also evaluated. No band op
    /// refers to it; its nodes need not start at 0.
    Midpoints,
}

impl Banding {
    /// The grid on `side` of the banding.
    pub fn grid_on(&self, side: BandSide) -> GridId {
        match side {
            BandSide::Fine => self.fine,
            BandSide::Coarse => self.coarse,
        }
    }
}

/// A named result of the scene.
#[derive(Clone, Debug, PartialEq)]
pub struct Output {
    /// Name.
    pub name: String,
    /// The value.
    pub value: Value,
    /// Unit (base units), for display.
    pub unit: String,
    /// The kernel returns the value times `2^-exponent` (0 unless
    /// `passes::rescale` scaled it; readers multiply by `2^exponent`).
    pub exponent: i32,
}

/// A gradient the scene computes: d output / d param.
#[derive(Clone, Debug, PartialEq)]
pub struct GradOutput {
    /// Index into [`Function::outputs`].
    pub output: usize,
    /// Index into [`Function::params`].
    pub param: usize,
    /// The value (per base unit of the param); `None` until the adjoint pass runs.
    pub value: Option<Value>,
}

/// A gradient with respect to a trainable input (a weight tensor):
/// an array of the input's shape.
#[derive(Clone, Debug, PartialEq)]
pub struct InputGrad {
    /// Index into [`Function::outputs`].
    pub output: usize,
    /// Index into [`Function::inputs`].
    pub input: usize,
    /// The value; `None` until the adjoint pass runs.
    pub value: Option<Value>,
}

/// The value a scene `knob` was compiled with (its own or a `--knob`
/// override), in base units; printed by `--emit ir`.
#[derive(Clone, Debug, PartialEq)]
pub struct KnobValue {
    /// The knob's name.
    pub name: String,
    /// Its value in base units.
    pub value: f64,
    /// The unit of the value (`1` when dimensionless).
    pub unit: String,
}

/// A scene lowered to IR: everything one compiled kernel computes.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Function {
    /// Scene name.
    pub name: String,
    /// The scene's knobs, in declaration order, with the values compiled in.
    pub knobs: Vec<KnobValue>,
    /// Grids.
    pub grids: Vec<Grid>,
    /// Parameters.
    pub params: Vec<ParamInfo>,
    /// Inputs.
    pub inputs: Vec<InputInfo>,
    /// Instructions; value `%i` is defined by `insts[i]`.
    pub insts: Vec<Inst>,
    /// Requested outputs.
    pub outputs: Vec<Output>,
    /// Requested gradients with respect to params.
    pub grads: Vec<GradOutput>,
    /// Requested gradients with respect to trainable inputs.
    pub input_grads: Vec<InputGrad>,
    /// Grid-only arrays folded at compile time (see `passes::specialise`).
    pub tables: Vec<Table>,
    /// Working precision.
    pub precision: Precision,
    /// Accuracy of transcendental functions.
    pub math: MathMode,
    /// Multibanding of `cis` on grids (applied by `passes::multiband`).
    pub multiband: Multiband,
    /// Relative binning of likelihood sums (applied by `passes::relbin`).
    pub relative_binning: RelativeBinning,
    /// The coarse grids [`Op::Band`] ops refer to.
    pub bands: Vec<Banding>,
}

impl Function {
    /// Keeps the outputs `keep` accepts, and the gradients of those (a
    /// later prune drops what only the others needed).
    pub fn retain_outputs(&mut self, keep: impl Fn(&Output) -> bool) {
        // Each output's index among the kept ones, `None` if dropped.
        let new_index = indices_among_kept(self.outputs.iter().map(keep));
        let mut old = new_index.iter();
        self.outputs.retain(|_| old.next().is_some_and(Option::is_some));
        self.grads.retain_mut(|g| new_index[g.output].map(|n| g.output = n).is_some());
        self.input_grads.retain_mut(|g| new_index[g.output].map(|n| g.output = n).is_some());
    }

    /// Makes each named param (value in its declared unit) a constant
    /// and drops it from [`Function::params`], so that what it alone
    /// determines folds at compile time (a trained classifier's template
    /// spectra become `passes::specialise` tables). Errors name an unknown
    /// param, a value that is not finite, and a param some gradient is
    /// requested with respect to.
    pub fn freeze_params(&mut self, values: &[(String, f64)]) -> Result<(), String> {
        let mut frozen: Vec<Option<f64>> = vec![None; self.params.len()];
        for (name, value) in values {
            let Some(k) = self.params.iter().position(|p| &p.name == name) else {
                let names: Vec<&str> = self.params.iter().map(|p| p.name.as_str()).collect();
                return Err(format!("scene `{}` has no param `{name}` to freeze; params: {}", self.name, names.join(", ")));
            };
            if !value.is_finite() {
                return Err(format!("cannot freeze param `{name}` at {value}: not finite"));
            }
            if self.grads.iter().any(|g| g.param == k) {
                return Err(format!("cannot freeze param `{name}`: a gradient with respect to it is requested"));
            }
            frozen[k] = Some(value * self.params[k].scale);
        }
        let new_index = indices_among_kept(frozen.iter().map(Option::is_none));
        for inst in &mut self.insts {
            if let Op::Param(k) = inst.op {
                inst.op = match (frozen[k as usize], new_index[k as usize]) {
                    (Some(v), _) => Op::Const(v.to_bits()),
                    (None, Some(n)) => Op::Param(n as u32),
                    (None, None) => unreachable!("a param is either frozen or kept"),
                };
            }
        }
        for g in &mut self.grads {
            g.param = new_index[g.param].expect("gradients of frozen params were refused");
        }
        let mut kept = new_index.iter();
        self.params.retain(|_| kept.next().is_some_and(Option::is_some));
        Ok(())
    }

    /// Grid `g`.
    pub fn grid(&self, g: GridId) -> &Grid {
        &self.grids[g.0 as usize]
    }

    /// The grid a value of shape `s` lives on (`None` for a scalar).
    pub fn grid_of(&self, s: Shape) -> Option<&Grid> {
        match s {
            Shape::Scalar => None,
            Shape::Grid(g) => Some(self.grid(g)),
        }
    }

    /// Type of `v`.
    pub fn ty(&self, v: Value) -> Ty {
        self.insts[v.index()].ty
    }

    /// Whether array `v` is the same at every grid point: a broadcast
    /// scalar, or elementwise arithmetic on such (as `passes::rescale`
    /// writes a scaled scalar), looking at most `depth` ops deep.
    pub fn is_uniform(&self, v: Value, depth: u32) -> bool {
        match self.insts[v.index()].op {
            Op::Broadcast(..) => true,
            op @ (Op::Unary(..) | Op::Binary(..) | Op::PowConst(..)) if depth > 0 => {
                op.operands().iter().all(|&a| self.is_uniform(a, depth - 1))
            }
            _ => false,
        }
    }

    /// Whether the truth value `c` is an *interval condition*: an order
    /// comparison of a grid's coordinates with a uniform value
    /// ([`Function::is_uniform`]: a broadcast scalar), such as
    /// the ISCO cut `f <= f_isco`. Coordinates `start + i·step` are
    /// monotone in `i`, so such a condition holds on a prefix or a suffix
    /// of the grid. Returns the grid and whether the points where `c`
    /// holds come first.
    pub fn interval_condition(&self, c: Value) -> Option<(GridId, bool)> {
        let Op::Binary(op, x, y) = self.insts[c.index()].op else { return None };
        let below = match op {
            BinOp::Lt | BinOp::Le => true,
            BinOp::Gt | BinOp::Ge => false,
            _ => return None,
        };
        let is_scalar = |v: Value| self.is_uniform(v, 4);
        let (grid, coord_left) = match (self.insts[x.index()].op, self.insts[y.index()].op) {
            (Op::GridCoord(g), _) if is_scalar(y) => (g, true),
            (_, Op::GridCoord(g)) if is_scalar(x) => (g, false),
            _ => return None,
        };
        // `coord < s` holds first on an increasing grid; `s < coord` last.
        let increasing = self.grids[grid.0 as usize].step >= 0.0;
        Some((grid, below == coord_left && increasing || below != coord_left && !increasing))
    }

    /// The scalar constant behind `v`, looking through broadcasts.
    pub fn const_of(&self, v: Value) -> Option<num_complex::Complex64> {
        match self.insts[v.index()].op {
            Op::Const(b) => Some(num_complex::Complex64::new(f64::from_bits(b), 0.0)),
            Op::ConstComplex(r, i) => Some(num_complex::Complex64::new(f64::from_bits(r), f64::from_bits(i))),
            Op::Broadcast(a, _) => self.const_of(a),
            _ => None,
        }
    }

    /// Whether `v` is the constant zero (looking through broadcasts).
    pub fn is_zero(&self, v: Value) -> bool {
        self.const_of(v).is_some_and(|z| z.re == 0.0 && z.im == 0.0)
    }

    /// The number of elements a value of shape `s` holds.
    pub fn len_of(&self, s: Shape) -> usize {
        match s {
            Shape::Scalar => 1,
            Shape::Grid(g) => self.grids[g.0 as usize].len,
        }
    }

    /// All values the function returns (outputs, then computed gradients).
    pub fn roots(&self) -> Vec<Value> {
        self.outputs
            .iter()
            .map(|o| o.value)
            .chain(self.grads.iter().filter_map(|g| g.value))
            .chain(self.input_grads.iter().filter_map(|g| g.value))
            .collect()
    }

    /// Whether the scene asks for any gradient (of params or of weights).
    pub fn has_gradients(&self) -> bool {
        !self.grads.is_empty() || !self.input_grads.is_empty()
    }

    /// Renames every root (outputs and computed gradients) through `map`,
    /// after a pass renumbered the instructions.
    pub fn remap_roots(&mut self, map: impl Fn(Value) -> Value) {
        for o in &mut self.outputs {
            o.value = map(o.value);
        }
        for g in &mut self.grads {
            g.value = g.value.map(&map);
        }
        for g in &mut self.input_grads {
            g.value = g.value.map(&map);
        }
    }
}

/// For items kept or dropped (`keep`, in order): each kept item's index
/// among the kept ones, `None` for a dropped one.
fn indices_among_kept(keep: impl Iterator<Item = bool>) -> Vec<Option<usize>> {
    let mut kept = 0;
    keep.map(|k| {
        k.then(|| {
            kept += 1;
            kept - 1
        })
    })
    .collect()
}
