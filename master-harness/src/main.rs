//! `dnet-master`: see [`master_harness::cli`].

use std::io::IsTerminal;
use std::process::ExitCode;

fn main() -> ExitCode {
    let stdout = std::io::stdout();
    let terminal = stdout.is_terminal();
    let mut out = stdout.lock();
    let mut err = std::io::stderr();
    ExitCode::from(master_harness::cli::run(std::env::args_os(), &mut out, &mut err, terminal))
}
