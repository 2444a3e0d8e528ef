//! Inputs that cargo-fuzz found to crash or hang a reader (`scripts/fuzz.sh`,
//! targets in `fuzz/`), replayed through the same readers: each must now be
//! a clear error, returned quickly.

use gwml::runtime::dataset::Dataset;
use gwml::runtime::npy;
use std::path::Path;
use std::time::{Duration, Instant};

fn case(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz_cases").join(name)
}

/// Runs `f`, which must return an error containing `needle` within `limit`.
fn fails_fast<T: std::fmt::Debug, E: std::fmt::Display>(f: impl FnOnce() -> Result<T, E>, needle: &str, limit: Duration) {
    let start = Instant::now();
    let r = f();
    let took = start.elapsed();
    match r {
        Ok(v) => panic!("expected an error, got {v:?}"),
        Err(e) => assert!(e.to_string().contains(needle), "error `{e}` does not mention {needle:?}"),
    }
    assert!(took < limit, "took {took:?}");
}

/// A 247-byte `.npy` whose header nests `[` 120 deep: npyz's header parser
/// ran for minutes (exponential backtracking).
#[test]
fn npy_header_of_nested_brackets_is_rejected_at_once() {
    let path = case("npy_nested_header.npy");
    fails_fast(|| npy::read(&path), "nests brackets more than 8 deep", Duration::from_secs(1));
    fails_fast(|| Dataset::read(&path), "nests brackets more than 8 deep", Duration::from_secs(1));
}

/// A 10 kB GWOSC-layout file whose `strain/Strain` chunks declare 4 GB:
/// reading it allocated them.
#[test]
fn hdf5_with_huge_declared_chunks_is_rejected_before_allocating() {
    let path = case("hdf5_huge_chunks.hdf5");
    fails_fast(|| gwml_strain::gwosc::read(&path), "strain/Strain", Duration::from_secs(2));
}
