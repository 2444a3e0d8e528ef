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

/// How deep brackets may nest in a `.npy` header: a plain dtype's header
/// nests 2 deep, a structured one a few more.
const MAX_HEADER_NESTING: usize = 8;

/// Checks the start of a `.npy` file (`head`: at least its header, or the
/// whole file if shorter) before the header parser sees it: npyz's parser
/// takes time exponential in the nesting of brackets (found by
/// `scripts/fuzz.sh`: a 247-byte header of nested `[` ran for minutes), so
/// a header nested deeper than any dtype needs is an error here.
pub(crate) fn check_header(head: &[u8]) -> Result<(), String> {
    if head.len() < 10 || &head[..6] != b"\x93NUMPY" {
        return Ok(()); // npyz reports a wrong magic or a cut header itself
    }
    let (len, start) = match head[6] {
        1 => (u16::from_le_bytes([head[8], head[9]]) as usize, 10),
        _ if head.len() >= 12 => (u32::from_le_bytes([head[8], head[9], head[10], head[11]]) as usize, 12),
        _ => return Ok(()),
    };
    let header = &head[start.min(head.len())..(start + len).min(head.len())];
    let mut depth = 0usize;
    for &c in header {
        match c {
            b'[' | b'(' | b'{' => {
                depth += 1;
                if depth > MAX_HEADER_NESTING {
                    return Err(format!("its header nests brackets more than {MAX_HEADER_NESTING} deep; it is not a NumPy array header"));
                }
            }
            b']' | b')' | b'}' => depth = depth.saturating_sub(1),
            _ => {}
        }
    }
    Ok(())
}

/// Bytes to read before [`check_header`]: the header's size field is 4
/// bytes, so a real header fits in this unless it is larger than any dtype
/// needs (the check then sees its first 64 KiB).
pub(crate) const HEADER_PROBE: usize = 12 + 65536;

/// Reads a 1-D `.npy` array of float64, float32, complex128 or complex64.
pub fn read(path: &Path) -> Result<NpyData, Error> {
    let bytes = std::fs::read(path).map_err(|e| Error::Io(format!("cannot read {}: {e}", path.display())))?;
    check_header(&bytes[..bytes.len().min(HEADER_PROBE)]).map_err(|e| Error::Io(format!("{} is not a .npy file: {e}", path.display())))?;
    let open = || npyz::NpyFile::new(&bytes[..]).map_err(|e| Error::Io(format!("{} is not a .npy file: {e}", path.display())));
    let npy = open()?;
    let shape = npy.shape().to_vec();
    if shape.len() > 1 && shape.iter().filter(|d| **d > 1).count() > 1 {
        return Err(Error::Io(format!("{} has shape {shape:?}; gwml inputs are 1-D", path.display())));
    }
    // The header's size against the bytes that follow it, before anything
    // is allocated by it: a truncated or lying file is an error, not an
    // out-of-memory abort.
    let (values, item, dtype) = (npy.len(), npy.dtype().num_bytes(), npy.dtype());
    let held = npy.into_inner().len() as u64;
    if let Some(need) = item.and_then(|b| values.checked_mul(b as u64)) {
        if need != held {
            return Err(Error::Io(format!(
                "{}: the header declares {values} values ({need} bytes) but {held} bytes of data follow it; the file is truncated or corrupt",
                path.display()
            )));
        }
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
    Err(Error::Io(format!("{}: unsupported dtype {dtype:?}; use float64, float32, complex128 or complex64", path.display())))
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
        let scratch = tempfile::Builder::new().prefix("gwml-npy-").tempdir().unwrap();
        let dir = scratch.path();
        let p = dir.join("r.npy");
        write_real(&p, &[1.0, -2.5]).unwrap();
        assert_eq!(read(&p).unwrap(), NpyData { values: vec![C64::new(1.0, 0.0), C64::new(-2.5, 0.0)], complex: false });
        let p = dir.join("c.npy");
        write_complex(&p, &[C64::new(1.0, 2.0)]).unwrap();
        assert_eq!(read(&p).unwrap(), NpyData { values: vec![C64::new(1.0, 2.0)], complex: true });
    }

    /// A header claiming 10^12 values over 16 bytes of data, and a file cut
    /// short, are errors naming the file and the mismatch (no allocation by
    /// the header's size); a wrong magic is "not a .npy file".
    #[test]
    fn truncated_and_lying_files_are_clear_errors() {
        let scratch = tempfile::Builder::new().prefix("gwml-npy-bad-").tempdir().unwrap();
        let dir = scratch.path();
        let good = dir.join("good.npy");
        write_real(&good, &[1.0, 2.0]).unwrap();
        let bytes = std::fs::read(&good).unwrap();
        let shape = bytes.windows(4).position(|w| w == b"(2,)").expect("a 1-D shape in the header");
        let mut lying = bytes.clone();
        // Same header length: "(2,)" becomes "(1000000000000,)", eating padding.
        let claim = b"(1000000000000,)";
        lying.splice(shape..shape + 4, claim.iter().copied());
        let pad = lying[..].windows(claim.len() - 4).position(|w| w.iter().all(|b| *b == b' ')).unwrap();
        lying.drain(pad..pad + claim.len() - 4);
        let path = dir.join("lying.npy");
        std::fs::write(&path, &lying).unwrap();
        let err = read(&path).unwrap_err().to_string();
        assert!(err.contains("lying.npy") && err.contains("declares 1000000000000 values"), "{err}");
        let cut = dir.join("cut.npy");
        std::fs::write(&cut, &bytes[..bytes.len() - 3]).unwrap();
        let err = read(&cut).unwrap_err().to_string();
        assert!(err.contains("cut.npy") && err.contains("13 bytes of data follow"), "{err}");
        let magic = dir.join("magic.npy");
        std::fs::write(&magic, b"PK\x03\x04 not numpy").unwrap();
        assert!(read(&magic).unwrap_err().to_string().contains("is not a .npy file"));
    }
}
