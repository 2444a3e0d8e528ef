//! Reading and writing NumPy `.npy` files (1-D, real or complex, f64 or f32),
//! via the `npyz` crate.

use crate::Error;
use num_complex::{Complex, Complex64 as C64};
use std::path::Path;

/// Data read from a `.npy` file.
#[derive(Clone, Debug, PartialEq)]
pub struct NpyData {
    /// The values (real arrays have zero imaginary parts).
    pub values: Vec<C64>,
    /// Whether the file held complex numbers.
    pub complex: bool,
}

/// Reads a 1-D `.npy` array of float64, float32, complex128 or complex64.
pub fn read(path: &Path) -> Result<NpyData, Error> {
    let bytes = std::fs::read(path).map_err(|e| Error::Io(format!("cannot read {}: {e}", path.display())))?;
    let open = || npyz::NpyFile::new(&bytes[..]).map_err(|e| Error::Io(format!("{} is not a .npy file: {e}", path.display())));
    let npy = open()?;
    let shape = npy.shape().to_vec();
    if shape.len() > 1 && shape.iter().filter(|d| **d > 1).count() > 1 {
        return Err(Error::Io(format!("{} has shape {shape:?}; gwml inputs are 1-D", path.display())));
    }
    if let Ok(v) = open()?.into_vec::<f64>() {
        return Ok(NpyData { values: v.into_iter().map(|x| C64::new(x, 0.0)).collect(), complex: false });
    }
    if let Ok(v) = open()?.into_vec::<Complex<f64>>() {
        return Ok(NpyData { values: v, complex: true });
    }
    if let Ok(v) = open()?.into_vec::<f32>() {
        return Ok(NpyData { values: v.into_iter().map(|x| C64::new(x as f64, 0.0)).collect(), complex: false });
    }
    if let Ok(v) = open()?.into_vec::<Complex<f32>>() {
        return Ok(NpyData { values: v.into_iter().map(|z| C64::new(z.re as f64, z.im as f64)).collect(), complex: true });
    }
    Err(Error::Io(format!("{}: unsupported dtype {:?}; use float64, float32, complex128 or complex64", path.display(), npy.dtype())))
}

/// Writes a real array as float64.
pub fn write_real(path: &Path, data: &[f64]) -> Result<(), Error> {
    npyz::to_file_1d(path, data.iter().copied()).map_err(|e| Error::Io(format!("cannot write {}: {e}", path.display())))
}

/// Writes a complex array as complex128.
pub fn write_complex(path: &Path, data: &[C64]) -> Result<(), Error> {
    npyz::to_file_1d(path, data.iter().copied()).map_err(|e| Error::Io(format!("cannot write {}: {e}", path.display())))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_real_and_complex() {
        let dir = std::env::temp_dir().join(format!("gwml-npy-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("r.npy");
        write_real(&p, &[1.0, -2.5]).unwrap();
        assert_eq!(read(&p).unwrap(), NpyData { values: vec![C64::new(1.0, 0.0), C64::new(-2.5, 0.0)], complex: false });
        let p = dir.join("c.npy");
        write_complex(&p, &[C64::new(1.0, 2.0)]).unwrap();
        assert_eq!(read(&p).unwrap(), NpyData { values: vec![C64::new(1.0, 2.0)], complex: true });
    }
}
