//! Fuzz harnesses: feed arbitrary bytes to synthgen's readers through their public, file-based
//! entry points. Any panic is a bug; errors are the expected outcome. The same file is
//! compiled into the CLI tests (`tests/cli/corpus.rs`) to replay `fuzz/corpus/` as ordinary
//! tests.
#![allow(clippy::unwrap_used, clippy::expect_used)]
include!("harness.rs");
