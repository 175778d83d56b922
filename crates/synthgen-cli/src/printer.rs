//! Logs, warnings and progress bars on stderr; data on stdout. Bars are hidden when stderr is
//! not a terminal or with `--quiet`.

use std::io::{IsTerminal, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use synthgen_core::Progress;

pub struct Printer {
    quiet: bool,
    bar: Mutex<Option<ProgressBar>>,
    warnings: Mutex<Vec<String>>,
    stdout_closed: AtomicBool,
}

/// A line on stderr that a closed or full stderr loses instead of panicking (`eprintln!`
/// panics: `synthgen ... 2>&1 | head` must not end in a crash).
pub fn stderr_line(line: impl AsRef<str>) {
    let _ = writeln!(std::io::stderr().lock(), "{}", line.as_ref());
}

impl Printer {
    /// An `error:` line on stderr (a command's summary of what failed; always shown).
    pub fn error(&self, msg: impl AsRef<str>) {
        self.println(&format!("error: {}", msg.as_ref()));
    }

    pub fn new(quiet: bool) -> Self {
        Self {
            quiet,
            bar: Mutex::new(None),
            warnings: Mutex::new(Vec::new()),
            stdout_closed: AtomicBool::new(false),
        }
    }

    /// Data on stdout (tables, JSON, the viewer's address), written as given. A reader that
    /// went away (`synthgen stats D | head`) is no error: the rest of the data is dropped and
    /// the command still writes its files and returns its own status, as `ls` and `rg` end
    /// quietly. Any other write error (a full disk behind `> file`) is an error naming stdout.
    pub fn data(&self, text: impl AsRef<str>) -> std::io::Result<()> {
        if self.stdout_closed.load(Ordering::Relaxed) {
            return Ok(());
        }
        let mut out = std::io::stdout().lock();
        match out
            .write_all(text.as_ref().as_bytes())
            .and_then(|()| out.flush())
        {
            Ok(()) => Ok(()),
            Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => {
                self.stdout_closed.store(true, Ordering::Relaxed);
                Ok(())
            }
            Err(e) => Err(std::io::Error::new(
                e.kind(),
                format!("cannot write to standard output: {e}"),
            )),
        }
    }

    /// [`Printer::data`] with a line end.
    pub fn data_line(&self, text: impl AsRef<str>) -> std::io::Result<()> {
        self.data(format!("{}\n", text.as_ref()))
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
            // A closed or full stderr loses the message; it must not panic the command.
            _ => stderr_line(line),
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

    fn hint(&self, message: &str) {
        Printer::hint(self, message);
    }

    fn set_message(&self, message: &str) {
        Printer::set_message(self, message);
    }

    fn finish(&self) {
        if let Ok(mut b) = self.bar.lock() {
            if let Some(bar) = b.take() {
                bar.finish_and_clear();
            }
        }
    }
}
