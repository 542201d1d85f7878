//! PLACEHOLDER: the f64 oracle.
