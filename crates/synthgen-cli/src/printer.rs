//! Logs, warnings and progress bars on stderr; data on stdout. Bars are hidden when stderr is
//! not a terminal or with `--quiet`.

use std::io::IsTerminal;
use std::sync::Mutex;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use synthgen_core::Progress;

pub struct Printer {
    quiet: bool,
    bar: Mutex<Option<ProgressBar>>,
    warnings: Mutex<Vec<String>>,
}

impl Printer {
    pub fn new(quiet: bool) -> Self {
        Self {
            quiet,
            bar: Mutex::new(None),
            warnings: Mutex::new(Vec::new()),
        }
    }

    /// An informational line on stderr (suppressed by `--quiet`).
    pub fn info(&self, msg: impl AsRef<str>) {
        if !self.quiet {
            self.println(msg.as_ref());
        }
    }

    /// A `hint:` line telling the user what to do next.
    pub fn hint(&self, msg: impl AsRef<str>) {
        if !self.quiet {
            self.println(&format!("hint: {}", msg.as_ref()));
        }
    }

    /// Warnings are always shown, even with `--quiet`.
    pub fn warning(&self, msg: impl AsRef<str>) {
        let msg = msg.as_ref();
        if let Ok(mut w) = self.warnings.lock() {
            w.push(msg.to_string());
        }
        self.println(&format!("warning: {msg}"));
    }

    pub fn warning_count(&self) -> usize {
        self.warnings.lock().map(|w| w.len()).unwrap_or(0)
    }

    /// Replaces the progress bar's label, e.g. with a running loss.
    pub fn set_message(&self, msg: impl Into<String>) {
        if let Ok(b) = self.bar.lock() {
            if let Some(bar) = b.as_ref() {
                bar.set_message(msg.into());
            }
        }
    }

    fn println(&self, line: &str) {
        match self.bar.lock().ok().and_then(|b| b.clone()) {
            Some(bar) if !bar.is_hidden() => bar.println(line),
            _ => eprintln!("{line}"),
        }
    }

    fn make_bar(&self, label: &str, total: u64) -> ProgressBar {
        let target = if self.quiet || !std::io::stderr().is_terminal() {
            ProgressDrawTarget::hidden()
        } else {
            ProgressDrawTarget::stderr_with_hz(10)
        };
        let bar = ProgressBar::with_draw_target(Some(total), target);
        let style = ProgressStyle::with_template(
            "{msg:>10} [{bar:30}] {pos}/{len} {per_sec:.0} ({eta} left)",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .progress_chars("=> ");
        bar.set_style(style);
        bar.set_message(label.to_string());
        bar
    }
}

impl Progress for Printer {
    fn start(&self, label: &str, total: u64) {
        let bar = self.make_bar(label, total);
        if let Ok(mut b) = self.bar.lock() {
            if let Some(old) = b.replace(bar) {
                old.finish_and_clear();
            }
        }
    }

    fn advance(&self, n: u64) {
        if let Ok(b) = self.bar.lock() {
            if let Some(bar) = b.as_ref() {
                bar.inc(n);
            }
        }
    }

    fn warn(&self, message: &str) {
        self.warning(message);
    }

    fn info(&self, message: &str) {
        Printer::info(self, message);
    }

    fn finish(&self) {
        if let Ok(mut b) = self.bar.lock() {
            if let Some(bar) = b.take() {
                bar.finish_and_clear();
            }
        }
    }
}
