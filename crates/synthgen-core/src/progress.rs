//! Progress reporting from library code without printing: the binary implements this with
//! progress bars; tests and libraries use `NoProgress`.

pub trait Progress: Sync {
    /// Starts a phase with `total` steps (0 when unknown).
    fn start(&self, _label: &str, _total: u64) {}
    /// `n` more steps done.
    fn advance(&self, _n: u64) {}
    /// A non-fatal problem worth telling the user about (a missing texture, a fallback).
    fn warn(&self, _message: &str) {}
    /// An informational line (which units a mesh was read in, what was loaded), for a log.
    fn info(&self, _message: &str) {}
    /// What the user can do about the message just before (a flag to pass, a file to look at).
    fn hint(&self, _message: &str) {}
    /// A phase's label changed (which row, which epoch), without a new count.
    fn set_message(&self, _message: &str) {}
    fn finish(&self) {}
}

/// Reports nothing.
pub struct NoProgress;

impl Progress for NoProgress {}
