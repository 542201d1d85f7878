//! Build script: links Embree 3 only when the `embree` feature is enabled, so
//! the default build never needs the library installed.

use std::env;

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-env-changed=EMBREE_LIB_DIR");
    if env::var_os("CARGO_FEATURE_EMBREE").is_some() {
        // Optional non-system install location (Debian's package needs none).
        if let Some(dir) = env::var_os("EMBREE_LIB_DIR") {
            println!("cargo:rustc-link-search=native={}", dir.to_string_lossy());
        }
        println!("cargo:rustc-link-lib=embree3");
    }
}
