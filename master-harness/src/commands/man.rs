//! `dnet-master man DIR`: the manual pages in roff, generated from the command line's own
//! definition (`clap_mangen`), so they cannot drift: `dnet-master.1`, and one page per command,
//! `dnet-master-connect.1`, … with the command's own options and the options every command
//! shares. `man -l DIR/dnet-master-connect.1` shows one.

use clap::Args;
use harness_common::error::HarnessError;
use std::io::Write;
use std::path::{Path, PathBuf};

/// What `man` was asked.
#[derive(Args, Clone, Debug)]
pub struct ManArgs {
    /// The directory the pages are written into (created when missing).
    pub dir: PathBuf,
}

/// Writes the pages of `command` (`dnet-master`'s definition) into `args.dir` and lists them on
/// `out`; exit status 0.
pub fn execute(args: &ManArgs, mut command: clap::Command, out: &mut dyn Write) -> Result<u8, HarnessError> {
    let write_err = |path: &Path| {
        let path = path.display().to_string();
        move |source| HarnessError::Write { path, source }
    };
    std::fs::create_dir_all(&args.dir).map_err(write_err(&args.dir))?;
    // Built, every command carries the options every command shares (`global`).
    command.build();
    let mut pages = vec![("dnet-master".to_string(), command.clone())];
    for sub in command.get_subcommands().filter(|s| s.get_name() != "help" && !s.is_hide_set()) {
        let name = format!("dnet-master-{}", sub.get_name());
        let page = sub.clone().name(name.clone()).version(harness_common::version());
        pages.push((name, page));
    }
    for (name, page) in pages {
        let path = args.dir.join(format!("{name}.1"));
        let mut roff = Vec::new();
        clap_mangen::Man::new(page).render(&mut roff).map_err(write_err(&path))?;
        std::fs::write(&path, roff).map_err(write_err(&path))?;
        writeln!(out, "{}", path.display()).map_err(write_err(Path::new("standard output")))?;
    }
    Ok(0)
}
