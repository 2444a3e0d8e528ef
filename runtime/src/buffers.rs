//! Kernel buffers: storage in each buffer's precision, allocated once per
//! kernel and reused, filled from bound data, read back as values.

use crate::{Error, Value};
use gwml_compiler::codegen::{BufferKind, Kernel};
use gwml_compiler::ir::{Function, Precision, Shape};

use num_complex::Complex64 as C64;

/// Storage for one buffer, in its precision (see `codegen::BufferInfo`).
pub(crate) enum Buffer {
    F64(Vec<f64>),
    F32(Vec<f32>),
}

impl Buffer {
    /// Allocates fallibly, so a scene over a huge grid is an error, not an abort.
    pub(crate) fn new(precision: Precision, floats: usize) -> Result<Buffer, Error> {
        fn zeros<T: Clone + Default>(n: usize) -> Result<Vec<T>, Error> {
            let mut v = Vec::new();
            v.try_reserve_exact(n).map_err(|_| {
                Error::Bind(format!("cannot allocate a buffer of {n} values: the scene's grids are too large for this machine's memory"))
            })?;
            v.resize(n, T::default());
            Ok(v)
        }
        Ok(match precision {
            Precision::F64 => Buffer::F64(zeros(floats)?),
            Precision::F32 | Precision::Mixed => Buffer::F32(zeros(floats)?),
        })
    }
    pub(crate) fn ptr(&mut self) -> *mut u8 {
        match self {
            Buffer::F64(v) => v.as_mut_ptr() as *mut u8,
            Buffer::F32(v) => v.as_mut_ptr() as *mut u8,
        }
    }
    /// The first `n` values times `scale`, in f64 (one pass, no per-element
    /// dispatch: outputs are read after every call).
    pub(crate) fn real(&self, n: usize, scale: f64) -> Vec<f64> {
        // Extended from exact-size iterators, so the copy vectorises and
        // nothing is zeroed first: outputs of 8,000 bins are copied on
        // every call.
        let mut out = Vec::with_capacity(n);
        match self {
            Buffer::F64(v) if scale == 1.0 => out.extend_from_slice(&v[..n]),
            Buffer::F64(v) => out.extend(v[..n].iter().map(|x| x * scale)),
            Buffer::F32(v) => out.extend(v[..n].iter().map(|x| *x as f64 * scale)),
        }
        out
    }

    /// The first `n` interleaved (re, im) pairs times `scale`, as complex numbers.
    pub(crate) fn complex(&self, n: usize, scale: f64) -> Vec<C64> {
        let mut out = Vec::with_capacity(n);
        match self {
            Buffer::F64(v) => out.extend(v[..2 * n].chunks_exact(2).map(|c| C64::new(c[0] * scale, c[1] * scale))),
            Buffer::F32(v) => out.extend(v[..2 * n].chunks_exact(2).map(|c| C64::new(c[0] as f64 * scale, c[1] as f64 * scale))),
        }
        out
    }
}

/// Which kernel something was made for: its address, compared and never
/// dereferenced (a plain number, so a `Run` can move between threads; the
/// scene a run borrows keeps its kernels in place).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct KernelKey(usize);

impl KernelKey {
    pub(crate) fn of(kernel: &Kernel) -> KernelKey {
        KernelKey(kernel as *const Kernel as usize)
    }
}

/// The buffers of one kernel and its scalar slots, kept between calls.
#[derive(Default)]
pub(crate) struct Buffers {
    pub(crate) scratch: Vec<(bool, Buffer)>,
    /// Which kernel's layout `scratch` was allocated for.
    allocated_for: Option<KernelKey>,
    /// Which kernel's tables and inputs the buffers hold (but inputs the
    /// caller says are stale), or `None`: buffers are refilled only then.
    filled_for: Option<KernelKey>,
    /// The caller's count of data bindings when the inputs were last
    /// filled: an input bound (or computed) after it is stale.
    filled_at: u64,
    scalars: Vec<f64>,
}

impl Buffers {
    /// Whether these buffers were allocated for `kernel`.
    pub(crate) fn holds(&self, kernel: &Kernel) -> bool {
        self.allocated_for == Some(KernelKey::of(kernel))
    }

    /// The caller's binding count at the last fill (see [`Buffers::call`]).
    pub(crate) fn filled_at(&self) -> u64 {
        self.filled_at
    }

    /// Calls `kernel` (compiled from `func`) with `params` (base units),
    /// after filling the buffers of inputs `stale(i)` names (every input
    /// and table after a change of kernel) from `data(i)`; `bindings` is
    /// the caller's count of data bindings, kept as [`Buffers::filled_at`].
    pub(crate) fn call<'d>(
        &mut self,
        kernel: &Kernel,
        func: &Function,
        params: &[f64],
        data: &dyn Fn(usize) -> Result<&'d [C64], Error>,
        stale: &dyn Fn(usize) -> bool,
        bindings: u64,
    ) -> Result<(), Error> {
        let layout = &kernel.layout;
        let floats = |b: &gwml_compiler::codegen::BufferInfo| b.len * if b.complex { 2 } else { 1 };
        let refill_all = self.filled_for != Some(KernelKey::of(kernel));
        if self.allocated_for != Some(KernelKey::of(kernel)) {
            self.scratch =
                layout.buffers.iter().map(|b| Ok((b.complex, Buffer::new(b.precision, floats(b))?))).collect::<Result<_, Error>>()?;
            self.allocated_for = Some(KernelKey::of(kernel));
        }
        for ((_, buf), info) in self.scratch.iter_mut().zip(&layout.buffers) {
            match info.kind {
                BufferKind::Input(i) if refill_all || stale(i) => fill(buf, data(i)?, info.complex),
                BufferKind::Table(k) if refill_all => {
                    let data: Vec<C64> = func.tables[k].data.iter().map(|x| C64::new(*x, 0.0)).collect();
                    fill(buf, &data, false);
                }
                _ => {}
            }
        }
        self.filled_for = Some(KernelKey::of(kernel));
        self.filled_at = bindings;
        self.scalars.clear();
        self.scalars.resize(layout.scalar_slots, 0.0);
        let ptrs: Vec<*mut u8> = self.scratch.iter_mut().map(|(_, b)| b.ptr()).collect();
        // SAFETY: params has one entry per scene param; every buffer was
        // allocated from the kernel's own layout (length and precision), and
        // scalars has layout.scalar_slots entries.
        unsafe { kernel.call(params.as_ptr(), ptrs.as_ptr(), self.scalars.as_mut_ptr()) };
        Ok(())
    }

    /// Scalar root `v` of the last call.
    pub(crate) fn scalar(&self, kernel: &Kernel, v: gwml_compiler::ir::Value) -> Value {
        let s = kernel.layout.scalars.iter().find(|s| s.value == v).expect("every scalar root has a slot");
        if s.complex {
            Value::Complex(C64::new(self.scalars[s.slot], self.scalars[s.slot + 1]))
        } else {
            Value::Real(self.scalars[s.slot])
        }
    }

    /// Output number `oi` of `func` from the last call, at its true scale.
    pub(crate) fn output(&self, kernel: &Kernel, func: &Function, oi: usize) -> Value {
        let o = &func.outputs[oi];
        // Rescaled f32 kernels return outputs times 2^-exponent.
        let scale = 2f64.powi(o.exponent);
        if func.ty(o.value).shape == Shape::Scalar {
            match self.scalar(kernel, o.value) {
                Value::Real(x) => Value::Real(x * scale),
                Value::Complex(z) => Value::Complex(z * scale),
                other => other,
            }
        } else {
            let k = kernel.layout.outputs[oi].expect("array outputs have a buffer");
            let (complex, buf) = &self.scratch[k];
            let n = kernel.layout.buffers[k].len;
            if *complex {
                Value::ComplexArray(buf.complex(n, scale))
            } else {
                Value::RealArray(buf.real(n, scale))
            }
        }
    }
}

fn fill(buf: &mut Buffer, data: &[C64], complex: bool) {
    match buf {
        Buffer::F64(v) => {
            for (i, z) in data.iter().enumerate() {
                if complex {
                    v[2 * i] = z.re;
                    v[2 * i + 1] = z.im;
                } else {
                    v[i] = z.re;
                }
            }
        }
        Buffer::F32(v) => {
            for (i, z) in data.iter().enumerate() {
                if complex {
                    v[2 * i] = z.re as f32;
                    v[2 * i + 1] = z.im as f32;
                } else {
                    v[i] = z.re as f32;
                }
            }
        }
    }
}
