//! `dnet-sim-breaker`: the simulated intelligent circuit breaker on a serial port or pty (see
//! `--help`).

use clap::Parser;
use soft_slave::cli::{run_sim_breaker, SimBreakerArgs};
use soft_slave::error::SoftSlaveError;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

fn main() -> ExitCode {
    let args = SimBreakerArgs::parse();
    let stop = Arc::new(AtomicBool::new(false));
    let flag = Arc::clone(&stop);
    if let Err(e) = ctrlc::set_handler(move || flag.store(true, Ordering::Relaxed)) {
        eprintln!("dnet-sim-breaker: error: {}", SoftSlaveError::Signal(e.to_string()));
        return ExitCode::from(1);
    }
    match run_sim_breaker(&args, &stop, Box::new(std::io::stdout())) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("dnet-sim-breaker: error: {e}");
            ExitCode::from(e.exit_code())
        }
    }
}
