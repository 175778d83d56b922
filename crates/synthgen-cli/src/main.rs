use std::process::ExitCode;

fn main() -> ExitCode {
    synthgen_cli::main()
}
