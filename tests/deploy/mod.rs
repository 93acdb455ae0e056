//! Helpers of `tests/deploy_files.rs`: splitting the deploy files' command lines as their
//! runners do, and parsing HTCondor policy expressions.

pub mod classad;
pub mod words;
