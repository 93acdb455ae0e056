//! The worker runtime: `gridlight worker --master HOST:PORT`.
//!
//! - [`cache`]: the hash-keyed on-disk asset cache.
//! - [`backoff`]: reconnect delays.

pub mod backoff;
pub mod cache;
