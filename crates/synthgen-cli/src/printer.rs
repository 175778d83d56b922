//! Logs, warnings and progress bars on stderr; data on stdout. Bars are hidden when stderr is
//! not a terminal or with `--quiet`; without a terminal a long phase prints plain progress
//! lines instead (at a bounded rate, [`PlainLines`]), so a log shows that it is alive.

use std::fmt::Write as _;
use std::io::{IsTerminal, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressState, ProgressStyle};
use synthgen_core::Progress;

/// The bar's template. No key carries a style: a colour can be the terminal's own background
/// (`{per_sec:.0}` was colour 0, black, unreadable on a dark terminal) and output must read
/// without colour. `{rate}` is [`rate_key`]'s.
const BAR_TEMPLATE: &str = "{msg:>10} [{bar:30}] {pos}/{len} {rate} ({eta} left)";

/// Steps per second with a precision that fits the number (indicatif's `{per_sec}` prints up
/// to four decimals).
fn format_rate(per_sec: f64) -> String {
    if !per_sec.is_finite() {
        "-/s".to_string()
    } else if per_sec >= 100.0 {
        format!("{per_sec:.0}/s")
    } else if per_sec >= 1.0 {
        format!("{per_sec:.1}/s")
    } else {
        format!("{per_sec:.2}/s")
    }
}

fn rate_key(state: &ProgressState, w: &mut dyn std::fmt::Write) {
    let _ = w.write_str(&format_rate(state.per_sec()));
}

fn bar_style() -> ProgressStyle {
    ProgressStyle::with_template(BAR_TEMPLATE)
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .with_key("rate", rate_key)
        .progress_chars("=> ")
}

/// "1 min 05 s", "12 s", "0.4 s".
fn format_duration(d: Duration) -> String {
    let s = d.as_secs_f64();
    if s < 10.0 {
        format!("{s:.1} s")
    } else if s < 60.0 {
        format!("{s:.0} s")
    } else {
        let s = s.round() as u64;
        if s < 3600 {
            format!("{} min {:02} s", s / 60, s % 60)
        } else {
            format!("{} h {:02} min", s / 3600, (s % 3600) / 60)
        }
    }
}

/// When a phase's progress goes to stderr as plain lines (no terminal, no `--quiet`): nothing
/// for a phase that ends within [`PlainLines::FIRST`]; then a line at most every
/// [`PlainLines::EVERY`], and only once another tenth of the phase is done or
/// [`PlainLines::SLOW`] has passed; and a last line when a phase that printed one ends.
#[derive(Debug, Clone)]
pub struct PlainLines {
    started: Instant,
    /// When the last line was printed, at which position.
    last: Option<(Instant, u64)>,
}

impl PlainLines {
    pub const FIRST: Duration = Duration::from_secs(10);
    pub const EVERY: Duration = Duration::from_secs(10);
    pub const SLOW: Duration = Duration::from_secs(60);

    pub fn new(now: Instant) -> Self {
        Self {
            started: now,
            last: None,
        }
    }

    /// The line to print now that `pos` of `total` (0: unknown) steps are done, if one is due.
    pub fn advance(&mut self, label: &str, pos: u64, total: u64, now: Instant) -> Option<String> {
        let due = match self.last {
            None => now.duration_since(self.started) >= Self::FIRST,
            Some((at, at_pos)) => {
                let since = now.duration_since(at);
                let tenth = total.div_ceil(10).max(1);
                since >= Self::SLOW
                    || (since >= Self::EVERY && (total == 0 || pos >= at_pos + tenth))
            }
        };
        if !due {
            return None;
        }
        self.last = Some((now, pos));
        let elapsed = now.duration_since(self.started);
        let mut line = format!("{label}: {pos}");
        if let Some(pct) = (100 * pos).checked_div(total) {
            let _ = write!(line, "/{total} ({pct}%)");
        }
        let per_sec = pos as f64 / elapsed.as_secs_f64().max(1e-9);
        let _ = write!(
            line,
            ", {} in, {}",
            format_duration(elapsed),
            format_rate(per_sec)
        );
        if total > pos && pos > 0 {
            let left = Duration::from_secs_f64((total - pos) as f64 / per_sec);
            let _ = write!(line, ", ~{} left", format_duration(left));
        }
        Some(line)
    }

    /// The phase's last line, when it printed any.
    pub fn finish(&self, label: &str, pos: u64, total: u64, now: Instant) -> Option<String> {
        self.last?;
        let done = if total > 0 {
            format!("{pos}/{total}")
        } else {
            pos.to_string()
        };
        Some(format!(
            "{label}: {done} done in {}",
            format_duration(now.duration_since(self.started))
        ))
    }
}

/// A phase's bar (drawn on a terminal, else hidden but counting) and its plain lines.
struct Phase {
    bar: ProgressBar,
    plain: Option<PlainLines>,
}

impl Phase {
    /// Clears the bar; the plain lines' last line, if due.
    fn end(self) {
        self.bar.finish_and_clear();
        if let Some(plain) = &self.plain {
            let total = self.bar.length().unwrap_or(0);
            if let Some(line) = plain.finish(
                &self.bar.message(),
                self.bar.position(),
                total,
                Instant::now(),
            ) {
                stderr_line(line);
            }
        }
    }
}

pub struct Printer {
    quiet: bool,
    phase: Mutex<Option<Phase>>,
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
            phase: Mutex::new(None),
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
        if let Ok(p) = self.phase.lock() {
            if let Some(phase) = p.as_ref() {
                phase.bar.set_message(msg.into());
            }
        }
    }

    fn println(&self, line: &str) {
        let bar = self
            .phase
            .lock()
            .ok()
            .and_then(|p| p.as_ref().map(|p| p.bar.clone()));
        match bar {
            Some(bar) if !bar.is_hidden() => bar.println(line),
            // A closed or full stderr loses the message; it must not panic the command.
            _ => stderr_line(line),
        }
    }

    fn make_phase(&self, label: &str, total: u64) -> Phase {
        let terminal = std::io::stderr().is_terminal();
        let target = if self.quiet || !terminal {
            ProgressDrawTarget::hidden()
        } else {
            ProgressDrawTarget::stderr_with_hz(10)
        };
        let bar = ProgressBar::with_draw_target(Some(total), target);
        bar.set_style(bar_style());
        bar.set_message(label.to_string());
        Phase {
            bar,
            plain: (!self.quiet && !terminal).then(|| PlainLines::new(Instant::now())),
        }
    }
}

impl Progress for Printer {
    fn start(&self, label: &str, total: u64) {
        let phase = self.make_phase(label, total);
        let old = self.phase.lock().ok().and_then(|mut p| p.replace(phase));
        if let Some(old) = old {
            old.end();
        }
    }

    fn advance(&self, n: u64) {
        let line = match self.phase.lock() {
            Ok(mut p) => p.as_mut().and_then(|phase| {
                phase.bar.inc(n);
                let bar = &phase.bar;
                phase.plain.as_mut().and_then(|plain| {
                    plain.advance(
                        &bar.message(),
                        bar.position(),
                        bar.length().unwrap_or(0),
                        Instant::now(),
                    )
                })
            }),
            Err(_) => None,
        };
        if let Some(line) = line {
            stderr_line(line);
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
        let old = self.phase.lock().ok().and_then(|mut p| p.take());
        if let Some(old) = old {
            old.end();
        }
    }
}

#[cfg(test)]
mod tests {
    use std::sync::{Arc, Mutex};

    use indicatif::TermLike;

    use super::*;

    /// Every `{key:spec}` of the template: no spec may hold a style (`.name`), since a
    /// colour (`{per_sec:.0}` is colour 0, black) can vanish into the terminal's background.
    #[test]
    fn the_bar_template_styles_no_key() {
        for (i, _) in BAR_TEMPLATE.match_indices('{') {
            let key = &BAR_TEMPLATE[i + 1..i + BAR_TEMPLATE[i..].find('}').unwrap()];
            let spec = key.split_once(':').map_or("", |(_, s)| s);
            assert!(!spec.contains('.'), "{{{key}}} carries a style");
        }
    }

    #[derive(Debug, Clone, Default)]
    struct Screen(Arc<Mutex<String>>);

    impl TermLike for Screen {
        fn width(&self) -> u16 {
            100
        }
        fn move_cursor_up(&self, _: usize) -> std::io::Result<()> {
            Ok(())
        }
        fn move_cursor_down(&self, _: usize) -> std::io::Result<()> {
            Ok(())
        }
        fn move_cursor_right(&self, _: usize) -> std::io::Result<()> {
            Ok(())
        }
        fn move_cursor_left(&self, _: usize) -> std::io::Result<()> {
            Ok(())
        }
        fn write_line(&self, s: &str) -> std::io::Result<()> {
            self.0.lock().unwrap().push_str(&format!("{s}\n"));
            Ok(())
        }
        fn write_str(&self, s: &str) -> std::io::Result<()> {
            self.0.lock().unwrap().push_str(s);
            Ok(())
        }
        fn clear_line(&self) -> std::io::Result<()> {
            self.0.lock().unwrap().clear();
            Ok(())
        }
        fn flush(&self) -> std::io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn the_bar_shows_the_rate_as_plain_text() {
        let screen = Screen::default();
        let bar = ProgressBar::with_draw_target(
            Some(10),
            ProgressDrawTarget::term_like(Box::new(screen.clone())),
        );
        bar.set_style(bar_style());
        bar.set_message("rendering");
        bar.inc(4);
        std::thread::sleep(Duration::from_millis(20));
        bar.inc(1);
        let shown = screen.0.lock().unwrap().clone();
        assert!(
            shown.contains("rendering [") && shown.contains("] 5/10 "),
            "{shown:?}"
        );
        let rate = shown.split("] 5/10 ").nth(1).unwrap();
        let rate = rate.split(' ').next().unwrap();
        let number = rate
            .strip_suffix("/s")
            .unwrap_or_else(|| panic!("{shown:?}"));
        assert!(number.parse::<f64>().is_ok(), "{shown:?}");
        assert!(!shown.contains('\u{1b}'), "{shown:?}");
        assert_eq!(format_rate(1234.56), "1235/s");
        assert_eq!(format_rate(41.26), "41.3/s");
        assert_eq!(format_rate(0.123), "0.12/s");
    }

    /// Without a terminal (stderr a file or a pipe) a long phase says how far it is: nothing
    /// in its first 10 s, then a line per tenth of the phase at most every 10 s (or after a
    /// minute without a tenth), and a last line; a short phase prints nothing.
    #[test]
    fn a_long_phase_prints_bounded_plain_lines_a_short_one_none() {
        let t0 = Instant::now();
        let at = |s: u64| t0 + Duration::from_secs(s);
        let mut p = PlainLines::new(t0);
        assert_eq!(p.advance("refining", 50, 100, at(1)), None);
        assert_eq!(p.finish("refining", 100, 100, at(9)), None);
        assert_eq!(
            p.advance("refining", 55, 100, at(10)).as_deref(),
            Some("refining: 55/100 (55%), 10 s in, 5.5/s, ~8.2 s left")
        );
        // Under 10 s since the last line, then under a tenth more: nothing.
        assert_eq!(p.advance("refining", 70, 100, at(15)), None);
        assert_eq!(p.advance("refining", 64, 100, at(21)), None);
        assert!(p.advance("refining", 65, 100, at(22)).is_some());
        // A minute without a tenth.
        assert_eq!(p.advance("refining", 66, 100, at(60)), None);
        assert!(p.advance("refining", 66, 100, at(82)).is_some());
        assert_eq!(
            p.finish("refining", 100, 100, at(125)).as_deref(),
            Some("refining: 100/100 done in 2 min 05 s")
        );
        // An unknown total: a line every 10 s.
        let mut p = PlainLines::new(t0);
        assert_eq!(
            p.advance("loading", 3, 0, at(12)).as_deref(),
            Some("loading: 3, 12 s in, 0.25/s")
        );
        assert!(p.advance("loading", 4, 0, at(22)).is_some());
    }
}
