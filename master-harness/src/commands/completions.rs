//! `dnet-master completions SHELL`: the shell completion script of every command and option,
//! generated from the command line's own definition (`clap_complete`), so it cannot drift.
//!
//! Bash: `dnet-master completions bash > ~/.local/share/bash-completion/completions/dnet-master`.

use clap::Args;
use clap_complete::Shell;
use harness_common::error::HarnessError;
use std::io::Write;

/// What `completions` was asked.
#[derive(Args, Clone, Debug)]
pub struct CompletionsArgs {
    /// The shell: bash, zsh, fish, elvish or powershell.
    pub shell: Shell,
}

/// Writes the script of `command` (`dnet-master`'s definition) for `args.shell` to `out`; exit
/// status 0.
pub fn execute(
    args: &CompletionsArgs,
    mut command: clap::Command,
    out: &mut dyn Write,
) -> Result<u8, HarnessError> {
    let mut script = Vec::new();
    clap_complete::generate(args.shell, &mut command, "dnet-master", &mut script);
    out.write_all(&script)
        .map_err(|source| HarnessError::Write { path: "standard output".into(), source })?;
    Ok(0)
}
