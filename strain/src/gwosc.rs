//! GWOSC HDF5 strain files (placeholder: being written).
