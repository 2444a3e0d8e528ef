//! Labelled datasets in NumPy's `.npz` and `.npy` formats, read as f64.
//!
//! A [`Dataset`] is a set of named arrays whose first axis indexes the
//! examples (e.g. `x` with shape `[n, 1024]` and `label` with shape `[n]`).
//! [`Dataset::read`] accepts an `.npz` archive (as written by `np.savez` or
//! `np.savez_compressed`; every member becomes an array named without its
//! `.npy`) or a single `.npy` file (named after the file's stem). Element
//! types float64/32, int64/32/16/8, uint64/32/16/8 and bool are converted to
//! f64, integers only when exact (`|x| < 2^53`). [`write_npz`] writes f64
//! members that `np.load` reads back.

use crate::checkpoint::write_atomically;
use crate::Error;
use npyz::zip::write::FileOptions;
use npyz::zip::{CompressionMethod, ZipArchive};
use npyz::{DType, NpyFile, Order, TypeChar, WriterBuilder};
use std::collections::BTreeMap;
use std::io::{self, BufWriter, Cursor, Read};
use std::path::Path;

/// A row-major (C order) array of f64.
#[derive(Clone, Debug, PartialEq)]
pub struct Array {
    /// The dimensions (empty for a 0-D scalar).
    pub shape: Vec<usize>,
    /// The values in row-major order; as many as the product of `shape`.
    pub data: Vec<f64>,
}

impl Array {
    /// An array of shape `shape`; errors ([`Error::Bind`]) unless `data` has
    /// exactly as many values as the product of `shape`.
    pub fn new(shape: Vec<usize>, data: Vec<f64>) -> Result<Array, Error> {
        match element_count(&shape) {
            Some(n) if n == data.len() => Ok(Array { shape, data }),
            _ => Err(Error::Bind(format!("an array of shape {shape:?} cannot hold {} values", data.len()))),
        }
    }

    /// The number of rows: the length of axis 0, or 1 for a 0-D array.
    pub fn rows(&self) -> usize {
        self.shape.first().copied().unwrap_or(1)
    }

    /// The number of values in one row (the product of the dimensions after the first).
    pub fn row_len(&self) -> usize {
        self.shape.iter().skip(1).product()
    }

    /// The `i`-th slice along axis 0 (the whole array for a 0-D array).
    ///
    /// # Panics
    ///
    /// If `i >= self.rows()` or `data` is shorter than `shape` says, like
    /// slice indexing.
    pub fn row(&self, i: usize) -> &[f64] {
        assert!(i < self.rows(), "row {i} of an array with {} rows", self.rows());
        let len = self.row_len();
        &self.data[i * len..(i + 1) * len]
    }
}

/// Named arrays whose first axis indexes the examples.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Dataset {
    /// The arrays by name.
    pub arrays: BTreeMap<String, Array>,
}

/// The product of `shape`, or `None` on overflow.
fn element_count(shape: &[usize]) -> Option<usize> {
    shape.iter().try_fold(1usize, |a, &d| a.checked_mul(d))
}

/// The start of every `.npy` file.
const NPY_MAGIC: &[u8] = b"\x93NUMPY";

/// Exact f64 for integers with `|x| < 2^53`.
fn exact(x: i128) -> Option<f64> {
    (x.unsigned_abs() < 1u128 << 53).then_some(x as f64)
}

/// Converts integer elements to f64, failing on the first one that is not exact.
fn ints<T: Copy + Into<i128> + std::fmt::Display>(v: Vec<T>) -> Result<Vec<f64>, String> {
    v.iter()
        .enumerate()
        .map(|(i, &x)| exact(x.into()).ok_or_else(|| format!("element {i} ({x}) is too large to convert to f64 exactly (|x| ≥ 2^53)")))
        .collect()
}

/// Reads one `.npy` stream into an [`Array`]; errors are messages to be prefixed with where it came from.
fn read_npy(mut r: impl Read) -> Result<Array, String> {
    let mut head = Vec::new();
    r.by_ref().take(crate::npy::HEADER_PROBE as u64).read_to_end(&mut head).map_err(|e| format!("cannot read the array: {e}"))?;
    crate::npy::check_header(&head).map_err(|e| format!("not a valid .npy array: {e}"))?;
    let npy = NpyFile::new(Cursor::new(head).chain(r)).map_err(|e| format!("not a valid .npy array: {e}"))?;
    let shape = npy.shape().iter().map(|&d| usize::try_from(d).ok()).collect::<Option<Vec<usize>>>();
    let Some((shape, len)) = shape.and_then(|s| element_count(&s).map(|n| (s, n))) else {
        return Err(format!("shape {:?} is too large", npy.shape()));
    };
    if npy.order() == Order::Fortran && shape.len() >= 2 {
        return Err("is in Fortran order; save it in C order (np.ascontiguousarray)".into());
    }
    let dtype = npy.dtype();
    let unsupported = || format!("has dtype {}; use a float, integer or bool dtype", dtype.descr());
    let DType::Plain(ts) = &dtype else {
        return Err(unsupported());
    };
    let read = |e: io::Error| format!("cannot read the data ({e}); the file may be truncated");
    let data: Vec<f64> = match (ts.type_char(), ts.size_field()) {
        (TypeChar::Float, 8) => npy.into_vec::<f64>().map_err(read)?,
        (TypeChar::Float, 4) => npy.into_vec::<f32>().map_err(read)?.into_iter().map(f64::from).collect(),
        (TypeChar::Int, 8) => ints(npy.into_vec::<i64>().map_err(read)?)?,
        (TypeChar::Int, 4) => ints(npy.into_vec::<i32>().map_err(read)?)?,
        (TypeChar::Int, 2) => ints(npy.into_vec::<i16>().map_err(read)?)?,
        (TypeChar::Int, 1) => ints(npy.into_vec::<i8>().map_err(read)?)?,
        (TypeChar::Uint, 8) => ints(npy.into_vec::<u64>().map_err(read)?)?,
        (TypeChar::Uint, 4) => ints(npy.into_vec::<u32>().map_err(read)?)?,
        (TypeChar::Uint, 2) => ints(npy.into_vec::<u16>().map_err(read)?)?,
        (TypeChar::Uint, 1) => ints(npy.into_vec::<u8>().map_err(read)?)?,
        (TypeChar::Bool, 1) => npy.into_vec::<bool>().map_err(read)?.into_iter().map(|b| if b { 1.0 } else { 0.0 }).collect(),
        _ => return Err(unsupported()),
    };
    if data.len() != len {
        return Err(format!("has {} values for shape {shape:?}", data.len()));
    }
    Ok(Array { shape, data })
}

/// Reads every member of an `.npz` archive held in memory.
fn read_npz(bytes: &[u8]) -> Result<BTreeMap<String, Array>, String> {
    let mut zip = ZipArchive::new(Cursor::new(bytes)).map_err(|e| format!("not a valid .npz archive: {e}"))?;
    let mut arrays = BTreeMap::new();
    for i in 0..zip.len() {
        let mut member = zip.by_index(i).map_err(|e| format!("cannot read member {i}: {e}"))?;
        let file_name = member.name().to_string();
        let Some(name) = file_name.strip_suffix(".npy").filter(|n| !n.is_empty()) else {
            return Err(format!("member `{file_name}` is not a .npy array"));
        };
        let array = read_npy(&mut member).map_err(|e| format!("member `{file_name}` {e}"))?;
        // Read to the end so the zip reader checks the member's CRC.
        io::copy(&mut member, &mut io::sink()).map_err(|e| format!("member `{file_name}` is corrupt: {e}"))?;
        if arrays.insert(name.to_string(), array).is_some() {
            return Err(format!("holds two members named `{file_name}`"));
        }
    }
    Ok(arrays)
}

impl Dataset {
    /// Reads an `.npz` archive (every member, named without `.npy`) or a
    /// single `.npy` file (named after the file's stem), telling them apart
    /// by their contents. Errors ([`Error::Io`], naming the file) for an
    /// unreadable, truncated or corrupt file, a Fortran-order array with two
    /// or more axes, an unsupported element type, or an integer too large to
    /// be exact in f64.
    pub fn read(path: &Path) -> Result<Dataset, Error> {
        let bytes = std::fs::read(path).map_err(|e| Error::Io(format!("cannot read {}: {e}", path.display())))?;
        // The readers are not hardened against every malformed input: npyz
        // multiplies a header's shape out unchecked, which panics on overflow
        // in builds with overflow checks. Such a panic is turned into an
        // error rather than taking the caller down (with panic = "unwind",
        // the default).
        let parsed = std::panic::catch_unwind(|| -> Result<BTreeMap<String, Array>, String> {
            if bytes.starts_with(NPY_MAGIC) {
                let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
                let array = read_npy(&bytes[..])?;
                Ok(BTreeMap::from([(stem, array)]))
            } else if bytes.starts_with(b"PK") {
                read_npz(&bytes)
            } else {
                Err("is neither a .npy file nor an .npz archive".into())
            }
        });
        match parsed {
            Ok(Ok(arrays)) => Ok(Dataset { arrays }),
            Ok(Err(msg)) => Err(Error::Io(format!("{}: {msg}", path.display()))),
            Err(_) => Err(Error::Io(format!("{}: malformed file (the reader failed)", path.display()))),
        }
    }

    /// The number of examples: the common number of rows of all arrays.
    /// Errors ([`Error::Bind`]) naming two arrays whose first dimensions
    /// differ, or when there are no arrays.
    pub fn examples(&self) -> Result<usize, Error> {
        let mut arrays = self.arrays.iter();
        let Some((first, a)) = arrays.next() else {
            return Err(Error::Bind("the dataset has no arrays".into()));
        };
        for (name, b) in arrays {
            if b.rows() != a.rows() {
                return Err(Error::Bind(format!(
                    "dataset arrays disagree on the number of examples: `{first}` has {} rows but `{name}` has {}",
                    a.rows(),
                    b.rows()
                )));
            }
        }
        Ok(a.rows())
    }

    /// The first `n` examples (all of them when there are fewer): every
    /// array cut to its first `n` rows (0-D arrays are kept whole).
    pub fn head(&self, n: usize) -> Dataset {
        let arrays = self
            .arrays
            .iter()
            .map(|(name, a)| {
                if a.shape.is_empty() {
                    return (name.clone(), a.clone());
                }
                let rows = a.rows().min(n);
                let mut shape = a.shape.clone();
                if let Some(first) = shape.first_mut() {
                    *first = rows;
                }
                (name.clone(), Array { shape, data: a.data[..rows * a.row_len()].to_vec() })
            })
            .collect();
        Dataset { arrays }
    }

    /// The array called `name`; errors ([`Error::Bind`]) listing the names there are.
    pub fn get(&self, name: &str) -> Result<&Array, Error> {
        self.arrays.get(name).ok_or_else(|| {
            let names: Vec<&str> = self.arrays.keys().map(String::as_str).collect();
            let hint = gwml_compiler::front::diagnostics::did_you_mean(name, names.iter().copied())
                .map(|s| format!(" (did you mean `{s}`?)"))
                .unwrap_or_default();
            let have =
                if names.is_empty() { "none".to_string() } else { names.iter().map(|n| format!("`{n}`")).collect::<Vec<_>>().join(", ") };
            Error::Bind(format!("the dataset has no array `{name}`{hint}; it has {have}"))
        })
    }
}

/// Writes `ds` to `path` as an uncompressed `.npz` archive of float64
/// arrays (what `np.savez` writes), atomically: a temporary file in the same
/// directory, synced, then renamed over `path`. Errors with [`Error::Bind`]
/// (writing nothing) for an empty name or an array whose data length does not
/// match its shape, with [`Error::Io`] when writing fails.
pub fn write_npz(path: &Path, ds: &Dataset) -> Result<(), Error> {
    for (name, a) in &ds.arrays {
        if name.is_empty() {
            return Err(Error::Bind(format!("cannot write {}: an array has an empty name", path.display())));
        }
        if element_count(&a.shape) != Some(a.data.len()) {
            return Err(Error::Bind(format!(
                "cannot write {}: array `{name}` has shape {:?} but {} values",
                path.display(),
                a.shape,
                a.data.len()
            )));
        }
    }
    write_atomically(path, |file| {
        let mut npz = npyz::npz::NpzWriter::new(BufWriter::new(file));
        for (name, a) in &ds.arrays {
            // Zip64 fields only when a member could pass 4 GiB (header included).
            let large = (a.data.len() as u64).saturating_mul(8).saturating_add(1 << 16) > u64::from(u32::MAX);
            let options = FileOptions::default()
                .compression_method(CompressionMethod::Stored)
                .last_modified_time(npyz::zip::DateTime::default())
                .large_file(large);
            let shape: Vec<u64> = a.shape.iter().map(|&d| d as u64).collect();
            let mut w = npz.array::<f64>(name, options)?.default_dtype().shape(&shape).begin_nd()?;
            w.extend(a.data.iter().copied())?;
            w.finish()?;
        }
        let buffered = npz.zip_writer().finish().map_err(io::Error::other)?;
        buffered.into_inner().map_err(|e| e.into_error())
    })
}

/// Writes one array as an f64 `.npy` file of its shape, atomically (temp + rename).
pub fn write_npy(path: &Path, a: &Array) -> Result<(), Error> {
    if element_count(&a.shape) != Some(a.data.len()) {
        return Err(Error::Bind(format!("cannot write {}: shape {:?} but {} values", path.display(), a.shape, a.data.len())));
    }
    write_atomically(path, |file| {
        let shape: Vec<u64> = a.shape.iter().map(|&d| d as u64).collect();
        let mut buffered = BufWriter::new(file);
        let mut w = npyz::WriteOptions::new().default_dtype().shape(&shape).writer(&mut buffered).begin_nd()?;
        w.extend(a.data.iter().copied())?;
        w.finish()?;
        buffered.into_inner().map_err(|e| e.into_error())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fresh, empty directory for one test, removed when it is dropped.
    fn scratch(test: &str) -> tempfile::TempDir {
        tempfile::Builder::new().prefix(&format!("gwml-dataset-{test}-")).tempdir().unwrap()
    }

    fn sample() -> Dataset {
        let x: Vec<f64> = (0..12).map(|i| (i as f64).sin() * 1e-21).collect();
        Dataset {
            arrays: BTreeMap::from([
                ("x".to_string(), Array::new(vec![4, 3], x).unwrap()),
                ("label".to_string(), Array::new(vec![4], vec![0.0, 1.0, 1.0, -0.0]).unwrap()),
                ("snr".to_string(), Array::new(vec![4, 1, 1], vec![8.0, 12.5, f64::MAX, 1e-300]).unwrap()),
            ]),
        }
    }

    #[test]
    fn head_keeps_the_first_rows_of_every_array() {
        let ds = sample();
        let two = ds.head(2);
        assert_eq!(two.examples().unwrap(), 2);
        assert_eq!(two.arrays["x"].data, ds.arrays["x"].data[..6]);
        assert_eq!(two.arrays["label"].data, vec![0.0, 1.0]);
        assert_eq!(two.arrays["snr"].shape, vec![2, 1, 1]);
        assert_eq!(ds.head(10), ds);
    }

    #[test]
    fn a_2d_npy_round_trips() {
        let scratch = scratch("npy2d");
        let dir = scratch.path();
        let path = dir.join("y.npy");
        let a = Array::new(vec![2, 3], vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0]).unwrap();
        write_npy(&path, &a).unwrap();
        assert_eq!(Dataset::read(&path).unwrap().arrays["y"], a);
    }

    #[test]
    fn write_read_round_trip() {
        let scratch = scratch("round-trip");
        let dir = scratch.path();
        let path = dir.join("sub").join("train.npz");
        let ds = sample();
        write_npz(&path, &ds).unwrap();
        let back = Dataset::read(&path).unwrap();
        assert_eq!(back.arrays.keys().collect::<Vec<_>>(), ["label", "snr", "x"]);
        for (name, a) in &ds.arrays {
            let b = back.get(name).unwrap();
            assert_eq!(b.shape, a.shape);
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&b.data), bits(&a.data), "{name}");
        }
        assert_eq!(back.examples().unwrap(), 4);
        let x = back.get("x").unwrap();
        assert_eq!((x.rows(), x.row_len()), (4, 3));
        assert_eq!(x.row(2), &ds.arrays["x"].data[6..9]);
        // No temporary file is left behind, and overwriting works.
        let mut smaller = ds.clone();
        smaller.arrays.remove("snr");
        write_npz(&path, &smaller).unwrap();
        assert_eq!(Dataset::read(&path).unwrap(), smaller);
        let files: Vec<_> = std::fs::read_dir(path.parent().unwrap()).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(files, ["train.npz"]);
    }

    #[test]
    fn zero_d_and_empty_arrays() {
        let scratch = scratch("zero-d");
        let dir = scratch.path();
        let path = dir.join("d.npz");
        let ds = Dataset {
            arrays: BTreeMap::from([
                ("scalar".to_string(), Array::new(vec![], vec![2.5]).unwrap()),
                ("none".to_string(), Array::new(vec![0, 5], vec![]).unwrap()),
            ]),
        };
        write_npz(&path, &ds).unwrap();
        let back = Dataset::read(&path).unwrap();
        assert_eq!(back, ds);
        let s = back.get("scalar").unwrap();
        assert_eq!((s.rows(), s.row(0)), (1, &[2.5][..]));
        assert_eq!(back.get("none").unwrap().rows(), 0);
        assert!(Array::new(vec![2, 2], vec![1.0]).is_err());
    }

    #[test]
    fn reads_int64_labels_and_float32_features_from_npz() {
        let scratch = scratch("mixed");
        let dir = scratch.path();
        let path = dir.join("mixed.npz");
        {
            let mut npz = npyz::npz::NpzWriter::create(&path).unwrap();
            let opts = FileOptions::default();
            let mut w = npz.array::<i64>("label", opts).unwrap().default_dtype().shape(&[3]).begin_nd().unwrap();
            w.extend([0i64, 1, -(1 << 52)]).unwrap();
            w.finish().unwrap();
            let mut w = npz.array::<f32>("x", opts).unwrap().default_dtype().shape(&[3, 2]).begin_nd().unwrap();
            w.extend([0.5f32, -1.25, 3.0, 0.1, 1e-3, 7.0]).unwrap();
            w.finish().unwrap();
        }
        let ds = Dataset::read(&path).unwrap();
        assert_eq!(ds.examples().unwrap(), 3);
        assert_eq!(ds.get("label").unwrap(), &Array { shape: vec![3], data: vec![0.0, 1.0, -(2f64.powi(52))] });
        let x = ds.get("x").unwrap();
        assert_eq!(x.shape, vec![3, 2]);
        assert_eq!(x.row(1), &[3.0, f64::from(0.1f32)]);

        // A single .npy is named after its stem; other integer and bool types convert.
        let npy = dir.join("flags.npy");
        npyz::to_file_1d(&npy, [true, false, true]).unwrap();
        assert_eq!(Dataset::read(&npy).unwrap().get("flags").unwrap().data, vec![1.0, 0.0, 1.0]);
        let npy = dir.join("bytes.npy");
        npyz::to_file_1d(&npy, [255u8, 0, 7]).unwrap();
        assert_eq!(Dataset::read(&npy).unwrap().get("bytes").unwrap().data, vec![255.0, 0.0, 7.0]);
        let npy = dir.join("small.npy");
        npyz::to_file_1d(&npy, [-3i16, 300]).unwrap();
        assert_eq!(Dataset::read(&npy).unwrap().get("small").unwrap().data, vec![-3.0, 300.0]);
    }

    #[test]
    fn inexact_integers_fortran_order_and_other_dtypes_are_errors() {
        let scratch = scratch("inexact");
        let dir = scratch.path();
        let npy = dir.join("big.npy");
        npyz::to_file_1d(&npy, [1i64, 1 << 53]).unwrap();
        let err = Dataset::read(&npy).unwrap_err();
        assert!(matches!(&err, Error::Io(m) if m.contains("big.npy") && m.contains("element 1")), "{err}");
        let npy = dir.join("huge.npy");
        npyz::to_file_1d(&npy, [u64::MAX]).unwrap();
        assert!(Dataset::read(&npy).is_err());

        let npy = dir.join("fortran.npy");
        {
            let file = std::io::BufWriter::new(std::fs::File::create(&npy).unwrap());
            let mut w = npyz::WriteOptions::new().default_dtype().shape(&[2, 2]).order(Order::Fortran).writer(file).begin_nd().unwrap();
            w.extend([1.0f64, 2.0, 3.0, 4.0]).unwrap();
            w.finish().unwrap();
        }
        let err = Dataset::read(&npy).unwrap_err();
        assert!(matches!(&err, Error::Io(m) if m.contains("fortran.npy") && m.contains("Fortran")), "{err}");

        let npy = dir.join("complex.npy");
        npyz::to_file_1d(&npy, [num_complex::Complex64::new(1.0, 2.0)]).unwrap();
        let err = Dataset::read(&npy).unwrap_err();
        assert!(matches!(&err, Error::Io(m) if m.contains("dtype")), "{err}");
    }

    #[test]
    fn mismatched_rows_are_an_error() {
        let mut ds = sample();
        ds.arrays.insert("extra".into(), Array::new(vec![5], vec![0.0; 5]).unwrap());
        let err = ds.examples().unwrap_err();
        assert!(matches!(&err, Error::Bind(m) if m.contains("`extra`") && m.contains("`label`")), "{err}");
        assert!(Dataset::default().examples().is_err());
    }

    #[test]
    fn missing_name_is_an_error_listing_the_names() {
        let err = sample().get("lable").unwrap_err();
        assert!(matches!(&err, Error::Bind(m) if m.contains("`label`, `snr`, `x`") && m.contains("did you mean `label`")), "{err}");
    }

    #[test]
    fn garbage_and_truncated_files_are_errors() {
        let scratch = scratch("garbage");
        let dir = scratch.path();
        let garbage = dir.join("garbage.npz");
        std::fs::write(&garbage, b"PK not really a zip archive").unwrap();
        assert!(matches!(Dataset::read(&garbage), Err(Error::Io(m)) if m.contains("garbage.npz")));
        let text = dir.join("text.npy");
        std::fs::write(&text, b"hello").unwrap();
        assert!(matches!(Dataset::read(&text), Err(Error::Io(_))));
        assert!(matches!(Dataset::read(&dir.join("absent.npz")), Err(Error::Io(_))));

        let good = dir.join("good.npz");
        write_npz(&good, &sample()).unwrap();
        let bytes = std::fs::read(&good).unwrap();
        for cut in [2, 30, bytes.len() / 2, bytes.len() - 10] {
            let bad = dir.join(format!("cut{cut}.npz"));
            std::fs::write(&bad, &bytes[..cut]).unwrap();
            assert!(matches!(Dataset::read(&bad), Err(Error::Io(m)) if m.contains(&format!("cut{cut}"))));
        }
        // A flipped data byte (in the first member, `label`: a 128-byte .npy
        // header, then 32 bytes of data) fails the member's CRC check.
        let mut flipped = bytes.clone();
        let at = flipped.windows(NPY_MAGIC.len()).position(|w| w == NPY_MAGIC).unwrap() + 140;
        flipped[at] ^= 0x55;
        let bad = dir.join("flipped.npz");
        std::fs::write(&bad, &flipped).unwrap();
        assert!(matches!(Dataset::read(&bad), Err(Error::Io(_))));

        let npy = dir.join("short.npy");
        npyz::to_file_1d(&npy, [1.0f64, 2.0, 3.0]).unwrap();
        let bytes = std::fs::read(&npy).unwrap();
        std::fs::write(&npy, &bytes[..bytes.len() - 4]).unwrap();
        assert!(matches!(Dataset::read(&npy), Err(Error::Io(m)) if m.contains("short.npy")));
        // A header whose shape overflows when multiplied out.
        let mut header = "{'descr': '<f8', 'fortran_order': False, 'shape': (4294967296, 4294967296, 4294967296), }".to_string();
        while !(10 + header.len() + 1).is_multiple_of(64) {
            header.push(' ');
        }
        header.push('\n');
        let mut evil = NPY_MAGIC.to_vec();
        evil.extend([1, 0]);
        evil.extend((header.len() as u16).to_le_bytes());
        evil.extend(header.as_bytes());
        let npy = dir.join("evil.npy");
        std::fs::write(&npy, &evil).unwrap();
        assert!(matches!(Dataset::read(&npy), Err(Error::Io(_))));
    }
}
