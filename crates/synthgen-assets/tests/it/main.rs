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

/// `../shared/data` beside the checkout. The tests that use it are ignored where the build
/// script found none (`cfg(has_shared_data)`, synthgen-probe), so here it must exist.
pub fn shared_data() -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data");
    dir.canonicalize().unwrap_or_else(|e| {
        panic!(
            "shared data at {}: {e} (it was there when the tests were built, or SYNTHGEN_REQUIRE_SHARED=1)",
            dir.display()
        )
    })
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
