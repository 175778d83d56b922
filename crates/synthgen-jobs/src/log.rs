//! Where an experiment's messages go: a thin handle on the caller's [`Progress`] (the CLI's
//! progress bars and stderr lines, the Python package's logger, or nothing), with methods that
//! take owned or borrowed text.

use synthgen_core::Progress;

/// The caller's [`Progress`], for the experiments' messages and progress bars.
#[derive(Clone, Copy)]
pub struct Log<'a> {
    inner: &'a dyn Progress,
}

impl<'a> Log<'a> {
    pub fn new(inner: &'a dyn Progress) -> Log<'a> {
        Log { inner }
    }

    /// An informational line.
    pub fn info(&self, msg: impl AsRef<str>) {
        self.inner.info(msg.as_ref());
    }

    /// A non-fatal problem.
    pub fn warning(&self, msg: impl AsRef<str>) {
        self.inner.warn(msg.as_ref());
    }

    /// What the user can do about the message before.
    pub fn hint(&self, msg: impl AsRef<str>) {
        self.inner.hint(msg.as_ref());
    }

    /// Relabels the running phase (an epoch's loss).
    pub fn set_message(&self, msg: impl AsRef<str>) {
        self.inner.set_message(msg.as_ref());
    }

    /// The caller's progress, for library calls that report through it.
    pub fn progress(&self) -> &'a dyn Progress {
        self.inner
    }
}

impl Progress for Log<'_> {
    fn start(&self, label: &str, total: u64) {
        self.inner.start(label, total);
    }

    fn advance(&self, n: u64) {
        self.inner.advance(n);
    }

    fn warn(&self, message: &str) {
        self.inner.warn(message);
    }

    fn info(&self, message: &str) {
        self.inner.info(message);
    }

    fn hint(&self, message: &str) {
        self.inner.hint(message);
    }

    fn set_message(&self, message: &str) {
        self.inner.set_message(message);
    }

    fn finish(&self) {
        self.inner.finish();
    }
}
