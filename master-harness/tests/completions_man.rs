//! `dnet-master completions SHELL` and `dnet-master man DIR`: generated from the command line's
//! definition, checked against it (every command, its options), so neither can drift from it.

use clap::CommandFactory;
use master_harness::cli::Cli;
use std::path::PathBuf;
use std::process::{Command, Output};

fn dnet(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_dnet-master")).args(args).output().expect("run dnet-master")
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// Every command of `dnet-master` but clap's own `help`, with its long options.
fn commands() -> Vec<(String, Vec<String>)> {
    let mut cli = Cli::command();
    cli.build();
    cli.get_subcommands()
        .filter(|c| c.get_name() != "help")
        .map(|c| {
            let longs = c.get_arguments().filter_map(|a| a.get_long()).map(|l| format!("--{l}")).collect();
            (c.get_name().to_string(), longs)
        })
        .collect()
}

#[test]
fn the_definition_has_the_commands_the_tests_below_expect() {
    let names: Vec<String> = commands().into_iter().map(|(n, _)| n).collect();
    for expected in ["connect", "scan", "scanner", "ui", "conformance", "completions", "man"] {
        assert!(names.iter().any(|n| n == expected), "{expected} missing from {names:?}");
    }
}

#[test]
fn bash_completion_names_every_command_and_option() {
    let o = dnet(&["completions", "bash"]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    let script = text(&o.stdout);
    // bash's completion function, registered for the program.
    assert!(script.contains("complete -F _dnet__master") && script.contains(" dnet-master\n"), "{script}");
    for (name, longs) in commands() {
        // The subcommand's case in the script: `dnet__master,connect)` (clap_complete's naming).
        assert!(script.contains(&format!("dnet__master,{name})")), "no case for {name}");
        for long in longs {
            assert!(script.contains(&long), "{name}: {long} missing");
        }
    }
}

#[test]
fn zsh_and_fish_completions_name_every_command() {
    for shell in ["zsh", "fish"] {
        let o = dnet(&["completions", shell]);
        assert_eq!(o.status.code(), Some(0), "{shell}: {}", text(&o.stderr));
        let script = text(&o.stdout);
        for (name, _) in commands() {
            assert!(script.contains(&name), "{shell}: {name} missing");
        }
    }
}

#[test]
fn an_unknown_shell_is_a_usage_error() {
    let o = dnet(&["completions", "cmd.exe"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o.stderr).contains("cmd.exe"), "{}", text(&o.stderr));
    assert!(o.stdout.is_empty());
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("dnet-master-man-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

#[test]
fn man_writes_one_page_per_command_with_its_options() {
    let dir = temp_dir("pages");
    let o = dnet(&["man", dir.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    let listed = text(&o.stdout);
    let main = std::fs::read_to_string(dir.join("dnet-master.1")).expect("dnet-master.1");
    assert!(main.starts_with(".ie") || main.contains(".TH dnet-master 1"), "{main}");
    for (name, longs) in commands() {
        let file = dir.join(format!("dnet-master-{name}.1"));
        assert!(listed.contains(file.to_str().unwrap()), "{name} not listed: {listed}");
        let page = std::fs::read_to_string(&file).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
        assert!(page.contains(&format!(".TH dnet-master-{name} 1")), "{name}: no title\n{page}");
        assert!(page.contains(".SH NAME") && page.contains(".SH SYNOPSIS"), "{name}: sections\n{page}");
        // roff escapes every dash, the command's own too (serial-trace is serial\-trace).
        let listed_as = format!("dnet\\-master\\-{}(1)", name.replace('-', "\\-"));
        assert!(main.contains(&listed_as), "main page does not list {name} as {listed_as}");
        for long in longs {
            // roff escapes the dashes: --epr is \-\-epr.
            let escaped = long.replace('-', "\\-");
            assert!(page.contains(&escaped), "{name}: {long} missing");
        }
    }
    let connect = std::fs::read_to_string(dir.join("dnet-master-connect.1")).unwrap();
    for option in ["\\-\\-mac", "\\-\\-epr", "\\-\\-polls", "\\-\\-io", "\\-\\-bus", "\\-\\-master\\-mac"] {
        assert!(connect.contains(option), "connect page: {option} missing");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn man_into_a_path_that_is_a_file_fails_naming_it() {
    let file = temp_dir("file");
    std::fs::write(&file, "not a directory").unwrap();
    let o = dnet(&["man", file.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o.stderr).contains(file.to_str().unwrap()), "{}", text(&o.stderr));
    let _ = std::fs::remove_file(&file);
}
