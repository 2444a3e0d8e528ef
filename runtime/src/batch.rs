//! Batches: one scene evaluated for many parameter sets, spread over a
//! rayon thread pool.
//!
//! ```no_run
//! use gwml_runtime::batch::{Batch, Mode};
//! let model = gwml_runtime::Model::from_file("examples/chirp_fit.gw")?;
//! let scene = model.scene(None)?;
//! // Two params varied, three parameter sets (row-major, declared units).
//! let values = [28.0, 0.0, 29.0, 0.001, 30.0, 0.002];
//! let outs = scene.batch(&Batch::new(&["mc", "tc"], &values).mode(Mode::ValueAndGrad).threads(Some(2)))?;
//! for out in &outs {
//!     println!("{} {}", out.scalar("loss")?, out.grad("loss", "mc")?);
//! }
//! # Ok::<(), gwml_runtime::Error>(())
//! ```
//!
//! How the work is shared: each worker thread binds its own [`Run`] (fixed
//! params and shared inputs are bound once per thread, and the kernel's
//! buffers are allocated once per thread and reused for every item it
//! runs), then repeatedly claims the next unclaimed item index from a
//! shared counter, so a thread slowed down by the machine simply runs fewer
//! items. Results are put back in input order. Every item runs the same
//! kernel on the same inputs as a single [`Run`] would, so results are
//! bit-for-bit those of single runs, whatever the thread count.
//!
//! Errors: bad param names, a bad shape of `values`, shared inputs that do
//! not fit the scene, or a gradient kernel that fails to compile are
//! reported before any item runs. An item that fails (a value out of its
//! param's bounds, a non-finite output) makes the batch fail with
//! [`Error::Item`], carrying the item's index; when several fail, the
//! lowest index is reported. Items after a failed one may be skipped.

use crate::{Error, Outputs, Run, Scene};
use num_complex::Complex64 as C64;
use std::borrow::Cow;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Which kernel every item of a batch runs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Mode {
    /// The forward kernel ([`Run::forward`]).
    #[default]
    Forward,
    /// The fused forward+gradient kernel ([`Run::value_and_grad`]).
    ValueAndGrad,
}

/// Data bound to the same input in every item.
#[derive(Clone, Debug)]
enum Shared<'a> {
    Real(&'a [f64]),
    Complex(&'a [C64]),
}

/// What a batch varies, what it shares, and how it runs: built with
/// [`Batch::new`] and the setters, run with [`Scene::batch`].
#[derive(Clone, Debug)]
pub struct Batch<'a> {
    names: Vec<&'a str>,
    values: Cow<'a, [f64]>,
    fixed: Vec<(&'a str, f64)>,
    inputs: Vec<(&'a str, Shared<'a>)>,
    mode: Mode,
    threads: Option<usize>,
    /// From [`Batch::from_rows`]: the first row of the wrong length, and its length.
    bad_row: Option<(usize, usize)>,
}

impl<'a> Batch<'a> {
    /// A batch over the params `names`, with `values` row-major: item `i`
    /// sets `names[j]` to `values[i * names.len() + j]`, in the param's
    /// declared unit. Params not named keep their defaults (or
    /// [`Batch::set`]). Defaults: [`Mode::Forward`], rayon's global pool.
    pub fn new(names: &[&'a str], values: &'a [f64]) -> Batch<'a> {
        Batch {
            names: names.to_vec(),
            values: Cow::Borrowed(values),
            fixed: Vec::new(),
            inputs: Vec::new(),
            mode: Mode::Forward,
            threads: None,
            bad_row: None,
        }
    }

    /// A batch over the params `names` with one row of values per item
    /// (each row as long as `names`; checked when the batch runs).
    pub fn from_rows(names: &[&'a str], rows: &[Vec<f64>]) -> Batch<'a> {
        let mut b = Batch::new(names, &[]);
        // A row of the wrong length is reported by `Scene::batch`.
        b.bad_row = rows.iter().position(|r| r.len() != names.len()).map(|i| (i, rows[i].len()));
        if b.bad_row.is_none() {
            b.values = Cow::Owned(rows.concat());
        }
        b
    }

    /// Sets param `name` to `value` (declared unit) in every item.
    pub fn set(mut self, name: &'a str, value: f64) -> Batch<'a> {
        self.fixed.push((name, value));
        self
    }

    /// Binds real data to input `name` in every item (declared unit).
    pub fn input_real(mut self, name: &'a str, data: &'a [f64]) -> Batch<'a> {
        self.inputs.push((name, Shared::Real(data)));
        self
    }

    /// Binds complex data to input `name` in every item (declared unit).
    pub fn input_complex(mut self, name: &'a str, data: &'a [C64]) -> Batch<'a> {
        self.inputs.push((name, Shared::Complex(data)));
        self
    }

    /// Which kernel every item runs.
    pub fn mode(mut self, mode: Mode) -> Batch<'a> {
        self.mode = mode;
        self
    }

    /// `None`: rayon's global pool (as many threads as cores unless
    /// configured otherwise); `Some(1)`: every item on the calling thread;
    /// `Some(n)`: a pool of `n` threads built for this batch (building it
    /// costs of the order of 0.1 ms).
    pub fn threads(mut self, threads: Option<usize>) -> Batch<'a> {
        self.threads = threads;
        self
    }

    /// The number of items (rows of values).
    pub fn len(&self) -> usize {
        if self.names.is_empty() {
            0
        } else {
            self.values.len() / self.names.len()
        }
    }

    /// Whether the batch has no items.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// One item's result, tagged with its index.
type Done = Vec<(usize, Result<Outputs, Error>)>;

impl Scene {
    /// Runs the scene once per item of `batch` (its forward kernel, or the
    /// fused forward+gradient kernel, as [`Batch::mode`] says), spread over
    /// the threads [`Batch::threads`] asks for, and returns one [`Outputs`]
    /// per item in input order, each bit-for-bit what a single [`Run`] with
    /// the same params and inputs returns. See the [module docs](crate::batch)
    /// for how errors are reported.
    pub fn batch(&self, batch: &Batch<'_>) -> Result<Vec<Outputs>, Error> {
        batch.check(self)?;
        let n = batch.len();
        if n == 0 {
            return Ok(Vec::new());
        }
        if batch.mode == Mode::ValueAndGrad {
            // Compile once, here, so a codegen failure is not an item's error.
            self.gradient_kernel()?;
        }
        let next = AtomicUsize::new(0);
        let failed = AtomicUsize::new(usize::MAX);
        let work = || worker(self, batch, &next, &failed);
        let parts: Vec<Result<Done, Error>> = match batch.threads {
            Some(0) => return Err(Error::Bind("a batch needs at least one thread (threads: Some(0) given)".into())),
            Some(1) => vec![work()],
            Some(t) => rayon::ThreadPoolBuilder::new()
                .num_threads(t)
                .build()
                .map_err(|e| Error::Bind(format!("cannot start a pool of {t} threads for the batch: {e}")))?
                .broadcast(|_| work()),
            None => rayon::broadcast(|_| work()),
        };
        let mut slots: Vec<Option<Outputs>> = (0..n).map(|_| None).collect();
        let mut first_err: Option<(usize, Error)> = None;
        for part in parts {
            for (i, r) in part? {
                match r {
                    Ok(out) => slots[i] = Some(out),
                    Err(e) if first_err.as_ref().is_none_or(|(j, _)| i < *j) => first_err = Some((i, e)),
                    Err(_) => {}
                }
            }
        }
        if let Some((index, e)) = first_err {
            return Err(Error::Item { index, error: Box::new(e) });
        }
        slots
            .into_iter()
            .enumerate()
            .map(|(i, o)| o.ok_or_else(|| Error::Bind(format!("internal error: batch item {i} was not run"))))
            .collect()
    }
}

impl Batch<'_> {
    /// Checks everything that is not specific to one item, before any runs.
    fn check(&self, scene: &Scene) -> Result<(), Error> {
        if let Some((row, len)) = self.bad_row {
            return Err(Error::Bind(format!("batch row {row} has {len} values, but {} params are named", self.names.len())));
        }
        if self.names.is_empty() {
            return Err(Error::Bind("a batch needs at least one param name to vary".into()));
        }
        if !self.values.len().is_multiple_of(self.names.len()) {
            return Err(Error::Bind(format!(
                "batch values: {} numbers is not a whole number of rows of {} (one value per named param per item)",
                self.values.len(),
                self.names.len()
            )));
        }
        let params = &scene.ir().params;
        for (k, name) in self.names.iter().enumerate() {
            if !params.iter().any(|p| p.name == *name) {
                return Err(crate::unknown("param", name, params.iter().map(|p| p.name.as_str())));
            }
            if self.names[..k].contains(name) {
                return Err(Error::Bind(format!("batch: param `{name}` is named twice")));
            }
            if self.fixed.iter().any(|(f, _)| f == name) {
                return Err(Error::Bind(format!("batch: param `{name}` is both varied and set for every item")));
            }
        }
        // Binding once here reports bad fixed params and inputs up front.
        self.bind_shared(scene).map(drop)
    }

    /// A run with the fixed params and shared inputs bound.
    fn bind_shared<'s>(&self, scene: &'s Scene) -> Result<Run<'s>, Error> {
        let mut run = scene.bind();
        for (name, value) in &self.fixed {
            run.param(name, *value)?;
        }
        for (name, data) in &self.inputs {
            match data {
                Shared::Real(d) => run.input_real(name, d)?,
                Shared::Complex(d) => run.input_complex(name, d)?,
            };
        }
        Ok(run)
    }
}

/// One worker: claims item indices from `next` until none are left (or an
/// item before them failed), running each on this thread's own [`Run`].
fn worker(scene: &Scene, batch: &Batch<'_>, next: &AtomicUsize, failed: &AtomicUsize) -> Result<Done, Error> {
    let (n, k) = (batch.len(), batch.names.len());
    let mut done = Vec::new();
    let mut run: Option<Run<'_>> = None;
    loop {
        let i = next.fetch_add(1, Ordering::Relaxed);
        // `failed` only decreases, so a stale read is larger than the final
        // value: no item below the lowest failed index is ever skipped.
        if i >= n || i > failed.load(Ordering::Relaxed) {
            return Ok(done);
        }
        let run = match &mut run {
            Some(r) => r,
            // Bound lazily: a thread that finds no work binds nothing.
            None => run.insert(batch.bind_shared(scene)?),
        };
        let r = run_item(run, &batch.names, &batch.values[i * k..(i + 1) * k], batch.mode);
        if r.is_err() {
            failed.fetch_min(i, Ordering::Relaxed);
        }
        done.push((i, r));
    }
}

fn run_item(run: &mut Run<'_>, names: &[&str], row: &[f64], mode: Mode) -> Result<Outputs, Error> {
    for (name, value) in names.iter().zip(row) {
        run.param(name, *value)?;
    }
    match mode {
        Mode::Forward => run.forward(),
        Mode::ValueAndGrad => run.value_and_grad(),
    }
}
