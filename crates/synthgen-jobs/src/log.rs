//! Where a job's messages go: a thin handle on the caller's [`Progress`] (the CLI's progress
//! bars and stderr lines, the Python package's logger, or nothing), with methods that take
//! owned or borrowed text; and, for the jobs that print tables or JSON, the [`Stdout`] they
//! print into.

use std::sync::Mutex;

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

/// What a job prints on stdout (its tables, its JSON), kept as it is made, so that a caller has
/// it even when the job then fails.
#[derive(Debug, Default)]
pub struct Stdout(Mutex<String>);

impl Stdout {
    fn push(&self, text: &str) {
        if let Ok(mut s) = self.0.lock() {
            s.push_str(text);
        }
    }

    /// What was printed so far.
    pub fn take(&self) -> String {
        self.0
            .lock()
            .map(|mut s| std::mem::take(&mut *s))
            .unwrap_or_default()
    }
}

/// A job's messages to the caller's progress and its output to a [`Stdout`]: the methods of
/// the CLI's printer that a job's code calls.
pub(crate) struct Printer<'a> {
    log: Log<'a>,
    stdout: &'a Stdout,
}

impl<'a> Printer<'a> {
    pub(crate) fn new(progress: &'a dyn Progress, stdout: &'a Stdout) -> Printer<'a> {
        Printer {
            log: Log::new(progress),
            stdout,
        }
    }

    pub(crate) fn info(&self, msg: impl AsRef<str>) {
        self.log.info(msg);
    }

    pub(crate) fn warning(&self, msg: impl AsRef<str>) {
        self.log.warning(msg);
    }

    pub(crate) fn hint(&self, msg: impl AsRef<str>) {
        self.log.hint(msg);
    }

    /// The caller's progress, for a phase with a bar.
    pub(crate) fn progress(&self) -> &'a dyn Progress {
        self.log.progress()
    }

    /// Text for stdout, as it is.
    pub(crate) fn data(&self, text: impl AsRef<str>) -> anyhow::Result<()> {
        self.stdout.push(text.as_ref());
        Ok(())
    }

    /// Text for stdout with a line end.
    pub(crate) fn data_line(&self, text: impl AsRef<str>) -> anyhow::Result<()> {
        self.data(format!("{}\n", text.as_ref()))
    }
}

impl Progress for Printer<'_> {
    fn start(&self, label: &str, total: u64) {
        self.log.start(label, total);
    }
    fn advance(&self, n: u64) {
        self.log.advance(n);
    }
    fn warn(&self, message: &str) {
        self.log.warning(message);
    }
    fn info(&self, message: &str) {
        self.log.info(message);
    }
    fn hint(&self, message: &str) {
        self.log.hint(message);
    }
    fn set_message(&self, message: &str) {
        self.log.set_message(message);
    }
    fn finish(&self) {
        self.log.finish();
    }
}
