//! Build sharing, no code: this crate only depends on shared dependencies with the union
//! of the features the workspace turns on, so that `cargo run -p cps-cli`, `cargo build
//! -p cps-python` and `cargo test --workspace` resolve one feature set and compile each
//! dependency once. See its Cargo.toml; `.ci/feature-parity.py` keeps it complete.
//!
//! There is nothing to call: depending on the crate is all it does.
#![deny(missing_docs)]
