//! Integration tests of synthgen-assets, one module per area.

#![allow(clippy::unwrap_used, clippy::expect_used)]

mod errors;
mod gltf;
mod lmo;
mod obj;
mod ply;
mod ycb;

use std::path::PathBuf;
use std::sync::Mutex;

use synthgen_core::Progress;

/// `/work/shared/data`, or `None` (the caller prints why and skips) when absent.
pub fn shared_data() -> Option<PathBuf> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data");
    match dir.canonicalize() {
        Ok(d) => Some(d),
        Err(_) => {
            eprintln!("skipped: shared data not found at {}", dir.display());
            None
        }
    }
}

/// Collects warnings.
#[derive(Default)]
pub struct Warnings(Mutex<Vec<String>>);

impl Warnings {
    pub fn take(&self) -> Vec<String> {
        std::mem::take(&mut *self.0.lock().unwrap())
    }
}

impl Progress for Warnings {
    fn warn(&self, message: &str) {
        self.0.lock().unwrap().push(message.to_string());
    }
}
