//! The `synthgen` command-line tool. `main.rs` only calls [`main`]; argument structs live in
//! `cli.rs`, each command's flags mapped onto its library call (`synthgen_jobs`,
//! `synthgen_experiment`, ...) in `commands/<verb>.rs`.

// Data goes through `Printer::data` (a closed stdout ends quietly), messages through the
// printer or `printer::stderr_line`: `println!` and `eprintln!` panic on a closed pipe.
#![deny(clippy::print_stdout, clippy::print_stderr)]

use std::process::ExitCode;

use clap::Parser;
use synthgen_core::Progress;

pub mod alloc;
pub mod cli;
pub mod commands;
pub mod config;
pub mod guard;
pub mod printer;

pub use printer::Printer;

/// How a command ended. Exit codes: 0 ok; 1 bad input (a usage error, a broken or
/// inconsistent file, a frame or row that failed, a diverged training); 2 internal error (a
/// bug).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExitStatus {
    Success,
    Failure,
    Error,
}

impl From<ExitStatus> for ExitCode {
    fn from(s: ExitStatus) -> Self {
        match s {
            ExitStatus::Success => ExitCode::from(0),
            ExitStatus::Failure => ExitCode::from(1),
            ExitStatus::Error => ExitCode::from(2),
        }
    }
}

pub fn main() -> ExitCode {
    let cli = match cli::Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            // --help and --version print and succeed; a usage error is bad input (exit 1,
            // not clap's 2, which here means an internal error).
            let _ = e.print();
            return match e.kind() {
                clap::error::ErrorKind::DisplayHelp | clap::error::ErrorKind::DisplayVersion => {
                    ExitStatus::Success.into()
                }
                _ => ExitStatus::Failure.into(),
            };
        }
    };
    let printer = Printer::new(cli.quiet);
    if let Err(e) = synthgen_core::pose::set_rotation_tolerance(cli.rotation_tolerance) {
        printer::stderr_line(format!("error: --rotation-tolerance: {e}"));
        return ExitStatus::Failure.into();
    }
    let result = guard::check(&cli.command).and_then(|()| dispatch(cli.command, &printer));
    match result {
        Ok(status) => status.into(),
        Err(err) => {
            printer.finish();
            printer::stderr_line(format!("error: {err}"));
            for cause in err.chain().skip(1) {
                printer::stderr_line(format!("  caused by: {cause}"));
            }
            if let Some(hint) = commands::hint_for(&err) {
                printer::stderr_line(format!("hint: {hint}"));
            }
            commands::exit_status_for(&err).into()
        }
    }
}

/// Runs one command (its paths already checked by [`guard::check`]).
fn dispatch(command: cli::Command, printer: &Printer) -> anyhow::Result<ExitStatus> {
    match command {
        cli::Command::Render(args) => commands::render::run(*args, printer),
        cli::Command::Mix(args) => commands::mix::run(args, printer),
        cli::Command::Stats(args) => commands::stats::run(args, printer),
        cli::Command::Preview(args) => commands::preview::run(args, printer),
        cli::Command::View(args) => commands::view::run(args, printer),
        cli::Command::Annotate(args) => commands::annotate::run(args, printer),
        cli::Command::Export(cli::ExportCommand::Coco(args)) => {
            commands::export::run_coco(args, printer)
        }
        cli::Command::Convert(args) => commands::convert::run(args, printer),
        cli::Command::Validate(args) => commands::validate::run(args, printer),
        cli::Command::Train(args) => commands::train::run(*args, printer),
        cli::Command::Eval(args) => commands::eval::run(*args, printer),
        cli::Command::Merge(args) => commands::merge::run(args, printer),
        cli::Command::Detector(cli::DetectorCommand::Train(args)) => {
            commands::detector::run_train(args, printer)
        }
        cli::Command::Detector(cli::DetectorCommand::Run(args)) => {
            commands::detector::run_run(args, printer)
        }
        cli::Command::Detector(cli::DetectorCommand::Eval(args)) => {
            commands::detector::run_eval(args, printer)
        }
        cli::Command::Predict(args) => commands::predict::run(*args, printer),
        cli::Command::Ros(args) => commands::ros::run(*args, printer),
        cli::Command::Experiment(cli::ExperimentCommand::Mix(args)) => {
            commands::experiment::run_mix(args, printer)
        }
        cli::Command::Experiment(cli::ExperimentCommand::Sim2real(args)) => {
            commands::experiment::run_sim2real(args, printer)
        }
        cli::Command::Experiment(cli::ExperimentCommand::Rgb(args)) => {
            commands::experiment::run_rgb(args, printer)
        }
        cli::Command::Sensor(cli::SensorCommand::Fit(args)) => {
            commands::sensor::run_fit(args, printer)
        }
        cli::Command::Sensor(cli::SensorCommand::Compare(args)) => {
            commands::sensor::run_compare(args, printer)
        }
        cli::Command::Sensor(cli::SensorCommand::CompareRgb(args)) => {
            commands::sensor::run_compare_rgb(args, printer)
        }
        cli::Command::Model(cli::ModelCommand::Align(args)) => {
            commands::model::run_align(args, printer)
        }
        cli::Command::Scene(cli::SceneCommand::Fit(args)) => {
            commands::scene::run_fit(args, printer)
        }
    }
}
