//! `dnet-master --log FILE`: the file's format is the one `--format` names, else the one its
//! extension names, else candump (issue 33: `--log x.asc` used to write candump text into the
//! `.asc` file). Checked on the simulated bus; `slave-fw/soft-slave/tests/end_to_end_pty.rs`
//! checks the same over SLCAN on ptys, for `dnet-master` and `dnet-soft-slave` together.

use can_io::trace::{detect, read_trace, ReadOptions, TraceFormat};
use rstest::rstest;
use std::path::PathBuf;
use std::process::{Command, Output};

fn dnet(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_dnet-master")).args(args).output().expect("run dnet-master")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("dnet-master-log-format-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

#[rstest]
#[case::asc("bringup.asc", None, TraceFormat::Asc)]
#[case::asc_upper_case("BRINGUP.ASC", None, TraceFormat::Asc)]
#[case::trc("bringup.trc", None, TraceFormat::Trc)]
#[case::csv("bringup.csv", None, TraceFormat::Csv)]
#[case::log("bringup.log", None, TraceFormat::Candump)]
#[case::no_extension("bringup", None, TraceFormat::Candump)]
#[case::format_wins("given.asc", Some("candump"), TraceFormat::Candump)]
#[case::format_trc("given.log", Some("trc"), TraceFormat::Trc)]
fn the_log_is_written_in_the_format_its_extension_names_unless_format_is_given(
    #[case] name: &str,
    #[case] format: Option<&str>,
    #[case] want: TraceFormat,
) {
    let path = temp(name);
    let mut args = vec!["--bus", "sim", "--log", path.to_str().unwrap()];
    if let Some(f) = format {
        args.extend_from_slice(&["--format", f]);
    }
    args.extend_from_slice(&["connect", "--mac", "5"]);
    let o = dnet(&args);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let bytes = std::fs::read(&path).unwrap();
    assert_eq!(detect(&bytes), Some(want), "{name}:\n{}", String::from_utf8_lossy(&bytes));
    // Read back as that format (no hint from the name): the 30 frames of the bring-up and release.
    let trace = read_trace(&path, ReadOptions { strict: true, format: Some(want) }).unwrap();
    assert_eq!(trace.entries.len(), 30, "{name}");
}

#[rstest]
#[case::pcap("x.pcap", "the extension names pcap, which --log does not write")]
#[case::pcapng("x.pcapng", "the extension names pcapng, which --log does not write")]
#[case::blf("x.blf", "the extension names blf, which --log does not write")]
fn a_log_named_for_a_binary_format_is_a_usage_error(#[case] name: &str, #[case] message: &str) {
    let path = temp(name);
    let _ = std::fs::remove_file(&path);
    let o = dnet(&["--bus", "sim", "--log", path.to_str().unwrap(), "connect", "--mac", "5"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains(message), "{}", stderr(&o));
    assert!(!path.exists(), "nothing is written");
    // --format says what to write under that name.
    let o = dnet(&["--bus", "sim", "--log", path.to_str().unwrap(), "--format", "candump", "connect"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(detect(&std::fs::read(&path).unwrap()), Some(TraceFormat::Candump));
}
