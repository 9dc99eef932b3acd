//! `dnet-soft-slave`: the serial-to-DeviceNet converter as a Linux process (see `--help` and the
//! the guide: docs/src/integrator/soft-slave.md).

use clap::Parser;
use soft_slave::cli::{run_soft_slave, summary_text, SoftSlaveArgs};
use soft_slave::error::SoftSlaveError;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

fn main() -> ExitCode {
    let args = SoftSlaveArgs::parse();
    let stop = Arc::new(AtomicBool::new(false));
    let flag = Arc::clone(&stop);
    if let Err(e) = ctrlc::set_handler(move || flag.store(true, Ordering::Relaxed)) {
        eprintln!("dnet-soft-slave: error: {}", SoftSlaveError::Signal(e.to_string()));
        return ExitCode::from(1);
    }
    match run_soft_slave(&args, &stop, Box::new(std::io::stderr())) {
        Ok(summary) => {
            if !args.quiet {
                eprintln!("{}", summary_text(&summary));
            }
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("dnet-soft-slave: error: {e}");
            ExitCode::from(e.exit_code())
        }
    }
}
