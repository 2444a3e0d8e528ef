//! Checkpoints of named f64 tensors in the safetensors format.
//!
//! A safetensors file is an 8-byte little-endian header length, a JSON
//! header (each tensor's dtype, shape and byte range, plus free-form string
//! metadata under `__metadata__`), then the raw little-endian data. The
//! files load in Python with `safetensors.torch.load_file` or
//! `safetensors.numpy.load_file`.
//!
//! [`save`] writes atomically: a temporary file in the target's directory,
//! flushed to disk, then renamed over the target, so a crash mid-save leaves
//! either the old checkpoint or the new one, never a torn file.

use crate::Error;
use safetensors::tensor::{Metadata, SafeTensors, TensorView};
use safetensors::{Dtype, View};
use std::borrow::Cow;
use std::collections::{BTreeMap, HashMap, HashSet};
use std::fs::File;
use std::io;
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};

/// One named tensor: a row-major (C order) array of f64.
#[derive(Clone, Debug, PartialEq)]
pub struct Tensor {
    /// The tensor's name, unique within a checkpoint.
    pub name: String,
    /// The dimensions (empty for a scalar).
    pub shape: Vec<usize>,
    /// The values in row-major order; as many as the product of `shape`.
    pub data: Vec<f64>,
}

/// A set of named tensors and string metadata.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Checkpoint {
    /// The tensors ([`load`] returns them sorted by name).
    pub tensors: Vec<Tensor>,
    /// Free-form metadata, stored in the header's `__metadata__`.
    pub metadata: BTreeMap<String, String>,
}

impl Checkpoint {
    /// The tensor called `name`, if there is one.
    pub fn get(&self, name: &str) -> Option<&Tensor> {
        self.tensors.iter().find(|t| t.name == name)
    }
}

/// The header key safetensors reserves for metadata.
const METADATA_KEY: &str = "__metadata__";

/// Bytes before the JSON header: its length as a little-endian u64.
const HEADER_LEN_BYTES: usize = 8;

/// A borrowed f64 tensor that safetensors serialises as little-endian F64.
struct F64View<'a> {
    shape: &'a [usize],
    data: &'a [f64],
}

impl View for F64View<'_> {
    fn dtype(&self) -> Dtype {
        Dtype::F64
    }

    fn shape(&self) -> &[usize] {
        self.shape
    }

    fn data(&self) -> Cow<'_, [u8]> {
        Cow::Owned(self.data.iter().flat_map(|x| x.to_le_bytes()).collect())
    }

    fn data_len(&self) -> usize {
        self.data.len() * 8
    }
}

fn check(path: &Path, ck: &Checkpoint) -> Result<(), Error> {
    let fail = |msg: String| Err(Error::Bind(format!("cannot save checkpoint {}: {msg}", path.display())));
    let mut names = HashSet::new();
    for t in &ck.tensors {
        if t.name.is_empty() || t.name == METADATA_KEY {
            return fail(format!("`{}` is not a valid tensor name", t.name));
        }
        if !names.insert(t.name.as_str()) {
            return fail(format!("two tensors are named `{}`", t.name));
        }
        let Some(len) = t.shape.iter().try_fold(1usize, |a, &d| a.checked_mul(d)) else {
            return fail(format!("tensor `{}` has shape {:?}, too large", t.name, t.shape));
        };
        if len != t.data.len() {
            return fail(format!("tensor `{}` has shape {:?} ({len} values) but {} values", t.name, t.shape, t.data.len()));
        }
        if let Some(i) = t.data.iter().position(|x| !x.is_finite()) {
            return fail(format!("tensor `{}` value {i} is {} (not finite)", t.name, t.data[i]));
        }
    }
    Ok(())
}

/// Writes `ck` to `path` as a safetensors file (F64, little endian), with
/// `ck.metadata` in the header's `__metadata__`.
///
/// Atomic: the file is written under a temporary name in the same
/// directory, synced, and renamed over `path`; the directory is created if
/// missing. Errors with [`Error::Bind`] (and writes nothing) when a tensor's
/// shape does not match its data length, two tensors share a name, a name is
/// empty or `__metadata__`, or a value is not finite; with [`Error::Io`]
/// when writing fails.
pub fn save(path: &Path, ck: &Checkpoint) -> Result<(), Error> {
    check(path, ck)?;
    let views = ck.tensors.iter().map(|t| (t.name.as_str(), F64View { shape: &t.shape, data: &t.data }));
    let metadata = if ck.metadata.is_empty() {
        None
    } else {
        Some(ck.metadata.iter().map(|(k, v)| (k.clone(), v.clone())).collect::<HashMap<_, _>>())
    };
    let bytes =
        safetensors::serialize(views, metadata).map_err(|e| Error::Io(format!("cannot save checkpoint {}: {e}", path.display())))?;
    write_atomically(path, |mut file| {
        io::Write::write_all(&mut file, &bytes)?;
        Ok(file)
    })
}

/// Reads a safetensors checkpoint. F64 tensors are read as they are, F32
/// tensors are widened to f64; any other dtype, and a truncated or corrupt
/// file, is an [`Error::Io`] naming the path. Tensors come back sorted by
/// name. Values are not checked for finiteness.
pub fn load(path: &Path) -> Result<Checkpoint, Error> {
    let bytes = std::fs::read(path).map_err(|e| Error::Io(format!("cannot read checkpoint {}: {e}", path.display())))?;
    parse(&bytes, &path.display().to_string())
}

/// Reads a checkpoint from the bytes of a safetensors file (`origin` names
/// it in errors), as [`load`] does.
pub fn parse(bytes: &[u8], origin: &str) -> Result<Checkpoint, Error> {
    let corrupt = |msg: String| Error::Io(format!("{origin} is not a valid safetensors checkpoint: {msg}"));
    let (header_len, meta): (usize, Metadata) = SafeTensors::read_metadata(bytes).map_err(|e| corrupt(e.to_string()))?;
    let data = HEADER_LEN_BYTES.checked_add(header_len).and_then(|start| bytes.get(start..)).ok_or_else(|| corrupt("truncated".into()))?;
    let mut infos: Vec<_> = meta.tensors().into_iter().collect();
    infos.sort_by(|a, b| a.0.cmp(&b.0));
    let mut tensors = Vec::with_capacity(infos.len());
    for (name, info) in infos {
        let (start, end) = info.data_offsets;
        let raw = data.get(start..end).ok_or_else(|| corrupt(format!("tensor `{name}` lies outside the file")))?;
        // Checks that the byte count matches the dtype and shape.
        let view = TensorView::new(info.dtype, info.shape.clone(), raw).map_err(|e| corrupt(format!("tensor `{name}`: {e}")))?;
        let values: Vec<f64> = match view.dtype() {
            Dtype::F64 => raw.chunks_exact(8).map(|c| f64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]])).collect(),
            Dtype::F32 => raw.chunks_exact(4).map(|c| f64::from(f32::from_le_bytes([c[0], c[1], c[2], c[3]]))).collect(),
            other => {
                return Err(Error::Io(format!("checkpoint {origin}: tensor `{name}` has dtype {other:?}; only F64 and F32 can be loaded")))
            }
        };
        tensors.push(Tensor { name, shape: info.shape.clone(), data: values });
    }
    let metadata = meta.metadata().iter().flatten().map(|(k, v)| (k.clone(), v.clone())).collect();
    Ok(Checkpoint { tensors, metadata })
}

/// Distinguishes temporary files of concurrent saves within one process.
static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// Writes a file atomically: `write` fills a fresh temporary file in the
/// target's directory (`.<name>.tmp-<pid>-<n>`, created with the parent
/// directory if missing) and hands it back; the file is then synced to disk
/// and renamed over `path`. On any error the temporary file is removed and
/// an existing file at `path` is left as it was.
pub(crate) fn write_atomically(path: &Path, write: impl FnOnce(File) -> io::Result<File>) -> Result<(), Error> {
    let fail = |e: io::Error| Error::Io(format!("cannot write {}: {e}", path.display()));
    let Some(name) = path.file_name() else {
        return Err(Error::Io(format!("cannot write {}: not a file name", path.display())));
    };
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    std::fs::create_dir_all(dir).map_err(fail)?;
    let n = TEMP_COUNTER.fetch_add(1, Ordering::Relaxed);
    let tmp = dir.join(format!(".{}.tmp-{}-{n}", name.to_string_lossy(), std::process::id()));
    let result = File::options()
        .write(true)
        .create_new(true)
        .open(&tmp)
        .and_then(write)
        .and_then(|f| f.sync_all())
        .and_then(|()| std::fs::rename(&tmp, path));
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(fail(e));
    }
    // Make the rename itself durable; not every platform can open or sync a
    // directory, and the data is already safe, so failures are ignored.
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fresh, empty directory for one test, removed when it is dropped.
    fn scratch(test: &str) -> tempfile::TempDir {
        tempfile::Builder::new().prefix(&format!("gwml-checkpoint-{test}-")).tempdir().unwrap()
    }

    fn sample() -> Checkpoint {
        let cube: Vec<f64> = (0..24).map(|i| (i as f64 - 11.5) * 0.1).collect();
        Checkpoint {
            tensors: vec![
                Tensor { name: "b.cube".into(), shape: vec![2, 3, 4], data: cube },
                Tensor { name: "a.scalar".into(), shape: vec![], data: vec![std::f64::consts::PI] },
                Tensor { name: "c.odd".into(), shape: vec![5], data: vec![-0.0, f64::MIN_POSITIVE / 4.0, f64::MAX, -1e-300, 1.0 / 3.0] },
                Tensor { name: "d.empty".into(), shape: vec![0, 3], data: vec![] },
            ],
            metadata: BTreeMap::from([("step".to_string(), "1200".to_string()), ("model".to_string(), "chirp".to_string())]),
        }
    }

    fn bits(t: &Tensor) -> Vec<u64> {
        t.data.iter().map(|x| x.to_bits()).collect()
    }

    #[test]
    fn round_trip_is_bit_for_bit() {
        let scratch = scratch("round-trip");
        let dir = scratch.path();
        let path = dir.join("ck.safetensors");
        let ck = sample();
        save(&path, &ck).unwrap();
        let back = load(&path).unwrap();
        assert_eq!(back.metadata, ck.metadata);
        let names: Vec<&str> = back.tensors.iter().map(|t| t.name.as_str()).collect();
        assert_eq!(names, ["a.scalar", "b.cube", "c.odd", "d.empty"]);
        for t in &ck.tensors {
            let b = back.get(&t.name).unwrap();
            assert_eq!(b.shape, t.shape);
            assert_eq!(bits(b), bits(t), "{}", t.name);
        }
        assert!(back.get("missing").is_none());
        // No metadata round-trips as none.
        let bare = Checkpoint { tensors: vec![], metadata: BTreeMap::new() };
        save(&path, &bare).unwrap();
        assert_eq!(load(&path).unwrap(), bare);
    }

    #[test]
    fn truncated_and_garbage_files_are_errors() {
        let scratch = scratch("corrupt");
        let dir = scratch.path();
        let path = dir.join("ck.safetensors");
        save(&path, &sample()).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        for cut in [0, 4, 8, 20, bytes.len() / 2, bytes.len() - 1] {
            let bad = dir.join(format!("cut{cut}.safetensors"));
            std::fs::write(&bad, &bytes[..cut]).unwrap();
            let err = load(&bad).unwrap_err();
            assert!(matches!(&err, Error::Io(m) if m.contains(&format!("cut{cut}"))), "{err}");
        }
        let garbage = dir.join("garbage.safetensors");
        std::fs::write(&garbage, b"this is not a checkpoint at all, just some text").unwrap();
        assert!(matches!(load(&garbage), Err(Error::Io(_))));
        let huge = dir.join("huge.safetensors");
        std::fs::write(&huge, u64::MAX.to_le_bytes()).unwrap();
        assert!(matches!(load(&huge), Err(Error::Io(_))));
        assert!(matches!(load(&dir.join("absent.safetensors")), Err(Error::Io(_))));
    }

    #[test]
    fn save_leaves_no_temp_file_and_overwrites() {
        let scratch = scratch("atomic");
        let dir = scratch.path();
        let path = dir.join("nested").join("run").join("ck.safetensors");
        save(&path, &sample()).unwrap();
        let mut second = sample();
        second.tensors.truncate(1);
        second.metadata.insert("step".into(), "1300".into());
        save(&path, &second).unwrap();
        assert_eq!(load(&path).unwrap().tensors.len(), 1);
        assert_eq!(load(&path).unwrap().metadata["step"], "1300");
        let files: Vec<_> = std::fs::read_dir(path.parent().unwrap()).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(files, ["ck.safetensors"]);
        // A failed rename (the target is a directory) cleans up too.
        assert!(matches!(save(&dir.join("nested"), &second), Err(Error::Io(_))));
        let files: Vec<_> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(files, ["nested"]);
    }

    #[test]
    fn invalid_checkpoints_are_not_saved() {
        let scratch = scratch("invalid");
        let dir = scratch.path();
        let path = dir.join("ck.safetensors");
        let t = |name: &str, shape: Vec<usize>, data: Vec<f64>| Tensor { name: name.into(), shape, data };
        let bad = [
            vec![t("w", vec![2, 2], vec![1.0; 3])],
            vec![t("w", vec![1], vec![1.0]), t("w", vec![1], vec![2.0])],
            vec![t("w", vec![2], vec![1.0, f64::NAN])],
            vec![t("w", vec![1], vec![f64::NEG_INFINITY])],
            vec![t("__metadata__", vec![1], vec![1.0])],
            vec![t("", vec![1], vec![1.0])],
            vec![t("w", vec![usize::MAX, 2], vec![])],
        ];
        for tensors in bad {
            let ck = Checkpoint { tensors, metadata: BTreeMap::new() };
            assert!(matches!(save(&path, &ck), Err(Error::Bind(_))), "{ck:?}");
        }
        assert_eq!(std::fs::read_dir(dir).unwrap().count(), 0);
    }

    #[test]
    fn f32_tensors_load_widened_and_other_dtypes_are_errors() {
        let scratch = scratch("f32");
        let dir = scratch.path();
        let values: [f32; 3] = [1.5, -0.25, 0.1];
        let raw: Vec<u8> = values.iter().flat_map(|x| x.to_le_bytes()).collect();
        let ints: Vec<u8> = [7i32, 8].iter().flat_map(|x| x.to_le_bytes()).collect();
        let f32_view = TensorView::new(Dtype::F32, vec![3, 1], &raw).unwrap();
        let path = dir.join("f32.safetensors");
        std::fs::write(&path, safetensors::serialize([("w", f32_view)], None).unwrap()).unwrap();
        let ck = load(&path).unwrap();
        let w = ck.get("w").unwrap();
        assert_eq!(w.shape, vec![3, 1]);
        assert_eq!(w.data, values.iter().map(|&x| f64::from(x)).collect::<Vec<_>>());

        let int_view = TensorView::new(Dtype::I32, vec![2], &ints).unwrap();
        let path = dir.join("i32.safetensors");
        std::fs::write(&path, safetensors::serialize([("n", int_view)], None).unwrap()).unwrap();
        let err = load(&path).unwrap_err();
        assert!(matches!(&err, Error::Io(m) if m.contains("I32") && m.contains("i32.safetensors")), "{err}");
    }
}
