//! `dnet-master user add|remove|list FILE ...`: the console's users file
//! ([`dnet_scanner::accounts`]).
//!
//! `user add FILE NAME --role viewer|operator|engineer` reads the password as one line from
//! standard input (`printf '%s\n' "$PW" | dnet-master user add ...`; an empty one is refused),
//! stores only its argon2 hash and writes the file with mode 0600 (created when missing).
//! `user remove FILE NAME` removes an account, `user list FILE` prints each name and role.
//! Every refusal (a bad name or role, a name that exists, a file that does not load, naming the
//! file and line) is exit 2.

use clap::{Args, Subcommand};
use dnet_scanner::accounts::{AccountsError, Role, Users, MAX_PASSWORD};
use harness_common::error::HarnessError;
use std::io::{BufRead, Write};
use std::path::PathBuf;

/// What `user` was asked.
#[derive(Args, Clone, Debug)]
pub struct UserArgs {
    /// add, remove or list.
    #[command(subcommand)]
    pub action: UserAction,
}

/// The `user` subcommands.
#[derive(Subcommand, Clone, Debug)]
pub enum UserAction {
    /// Add an account; the password is one line read from standard input.
    Add {
        /// The users file (created when missing, mode 0600).
        file: PathBuf,
        /// The user name: letters, digits, `.`, `_`, `-`.
        name: String,
        /// viewer (sees), operator (also outputs and breaker commands) or engineer (also Set
        /// attributes, configuration, scan-list edits).
        #[arg(long, value_parser = parse_role)]
        role: Role,
    },
    /// Remove an account.
    Remove {
        /// The users file.
        file: PathBuf,
        /// The user name.
        name: String,
    },
    /// List the accounts: name and role.
    List {
        /// The users file.
        file: PathBuf,
    },
}

fn parse_role(text: &str) -> Result<Role, AccountsError> {
    text.parse()
}

/// Why `user` refused.
#[derive(Debug, thiserror::Error)]
enum UserError {
    #[error(transparent)]
    Accounts(#[from] AccountsError),
    #[error("reading the password from standard input: {0}")]
    Stdin(std::io::Error),
    #[error("no password on standard input (one line, not empty)")]
    NoPassword,
}

/// Runs `user`, reading a password from `input`; returns the exit status (2 for a refusal, said
/// on `err`).
pub fn execute(
    args: &UserArgs,
    input: &mut dyn BufRead,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> Result<u8, HarnessError> {
    let werr = |source| HarnessError::Write { path: "standard output".into(), source };
    match run(args, input, out) {
        Ok(()) => Ok(0),
        Err(e) => {
            writeln!(err, "error: {e}").map_err(werr)?;
            Ok(2)
        }
    }
}

fn run(args: &UserArgs, input: &mut dyn BufRead, out: &mut dyn Write) -> Result<(), UserError> {
    let io = |path: &PathBuf| {
        let path = path.clone();
        move |source| UserError::Accounts(AccountsError::Io { path, source })
    };
    match &args.action {
        UserAction::Add { file, name, role } => {
            let mut users = Users::load_or_empty(file)?;
            let mut line = String::new();
            // One line at most MAX_PASSWORD bytes (plus its end): more is refused by `add`.
            std::io::Read::take(&mut *input, MAX_PASSWORD as u64 + 2)
                .read_line(&mut line)
                .map_err(UserError::Stdin)?;
            let password = line.strip_suffix('\n').unwrap_or(&line);
            let password = password.strip_suffix('\r').unwrap_or(password);
            if password.is_empty() {
                return Err(UserError::NoPassword);
            }
            users.add(name, password, *role)?;
            users.save()?;
            writeln!(out, "{}: added {name} ({role})", file.display()).map_err(io(file))?;
        }
        UserAction::Remove { file, name } => {
            let mut users = Users::load(file)?;
            users.remove(name)?;
            users.save()?;
            writeln!(out, "{}: removed {name}", file.display()).map_err(io(file))?;
        }
        UserAction::List { file } => {
            let users = Users::load(file)?;
            for (name, role) in users.list() {
                writeln!(out, "{name}\t{role}").map_err(io(file))?;
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn user(args: &[&str], stdin: &str) -> (u8, String, String) {
        #[derive(clap::Parser)]
        struct Cli {
            #[command(flatten)]
            user: UserArgs,
        }
        let cli = <Cli as clap::Parser>::try_parse_from(std::iter::once("user").chain(args.iter().copied()))
            .unwrap();
        let (mut out, mut err) = (Vec::new(), Vec::new());
        let code = execute(&cli.user, &mut stdin.as_bytes(), &mut out, &mut err).unwrap();
        (code, String::from_utf8(out).unwrap(), String::from_utf8(err).unwrap())
    }

    #[test]
    fn add_list_remove() {
        let dir = std::env::temp_dir().join(format!("dnet-user-cmd-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("users.toml");
        let f = file.to_str().unwrap();
        assert_eq!(user(&["add", f, "ann", "--role", "engineer"], "pw one\n").0, 0);
        assert_eq!(user(&["add", f, "bo", "--role", "viewer"], "x\r\n").0, 0);
        let (code, _, err) = user(&["add", f, "cy", "--role", "viewer"], "\n");
        assert_eq!((code, err.as_str()), (2, "error: no password on standard input (one line, not empty)\n"));
        let (code, _, err) = user(&["add", f, "ann", "--role", "viewer"], "pw\n");
        assert_eq!(code, 2);
        assert!(err.contains("exists already"), "{err}");
        assert_eq!(user(&["list", f], "").1, "ann\tengineer\nbo\tviewer\n");
        let users = Users::load(&file).unwrap();
        assert_eq!(users.verify("ann", "pw one"), Some(Role::Engineer));
        assert_eq!(users.verify("bo", "x"), Some(Role::Viewer));
        assert_eq!(user(&["remove", f, "bo"], "").0, 0);
        assert_eq!(user(&["list", f], "").1, "ann\tengineer\n");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
