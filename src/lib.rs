//! gwml: a differentiable modelling language for gravitational-wave data
//! analysis, as a library.
//!
//! ```no_run
//! let model = gwml::compile_file("examples/chirp_fit.gw")?;
//! let scene = model.scene(Some("chirp_fit"))?;
//! let mut run = scene.bind();
//! run.param("mc", 30.0)?;
//! let out = run.value_and_grad()?; // one fused forward+backward call
//! println!("loss {} dloss/dmc {}", out.scalar("loss")?, out.grad("loss", "mc")?);
//! # Ok::<(), gwml::Error>(())
//! ```
//!
//! The compiler lives in [`compiler`] (re-exported `gwml-compiler`), the
//! runtime types at the crate root (re-exported `gwml-runtime`).

pub use gwml_compiler as compiler;
pub use gwml_runtime as runtime;
pub use gwml_runtime::{batch, npy, spectrum, Error, Model, Outputs, Run, Scene, Value};

/// Reads and checks a `.gw` file.
pub fn compile_file(path: impl AsRef<std::path::Path>) -> Result<Model, Error> {
    Model::from_file(path)
}

/// Checks `.gw` source text; `name` labels it in diagnostics.
pub fn compile_str(name: &str, text: &str) -> Result<Model, Error> {
    Model::from_source(name, text)
}
