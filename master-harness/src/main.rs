//! `dnet-master`: see [`master_harness::cli`].
//!
//! SIGINT and SIGTERM ask the running command to stop ([`harness_common::console`]): it keeps what
//! it recorded, releases the device and exits 130 / 143. A second signal while it winds down stops
//! the program at once, by the signal's default action.

use harness_common::console::Console;
use master_core::stop::{SIGINT, SIGTERM};
use std::io::IsTerminal;
use std::process::ExitCode;

fn main() -> ExitCode {
    let console = Console {
        stdout_terminal: std::io::stdout().is_terminal(),
        stderr_terminal: std::io::stderr().is_terminal(),
        ..Console::plain()
    };
    let asked = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    for signal in [SIGINT, SIGTERM] {
        // The second signal takes the default action (the first one set `asked`); the first sets
        // the stop.
        let hooked = signal_hook::flag::register_conditional_default(signal, std::sync::Arc::clone(&asked))
            .and_then(|_| signal_hook::flag::register(signal, std::sync::Arc::clone(&asked)))
            .and_then(|_| signal_hook::flag::register_usize(signal, console.stop.flag(), signal as usize));
        if let Err(e) = hooked {
            eprintln!("dnet-master: cannot handle signal {signal}: {e} (Ctrl-C will not keep the records)");
        }
    }
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    let mut err = std::io::stderr();
    ExitCode::from(master_harness::cli::run_with(std::env::args_os(), &mut out, &mut err, &console))
}
