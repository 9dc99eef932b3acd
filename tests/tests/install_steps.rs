//! The install steps of the test scripts (`scripts/lib/install.sh`), run by bash against stand-in
//! `apt-get`, `apt-cache`, `dpkg-query`, `sudo` and `id` commands that record how they were called.
//! The real ones would change this machine; the stand-ins answer as Debian's do for the cases
//! that broke the README's test command on a fresh machine:
//!
//! - a tool that is present is never installed again (Node.js and npm from NodeSource: apt must
//!   not be asked for Debian's `npm` beside them);
//! - a package whose installation would remove one of the machine's packages is refused, naming
//!   it (Debian 12's `qemu-system-arm` beside the image's newer `qemu-utils`);
//! - as a user who is not root, apt-get runs through `sudo`; without `sudo` the step fails and
//!   names the package to install;
//! - the toolchain `rust-toolchain.toml` pins is used as it is when rustup has it, the machine's
//!   stable toolchain is linked under its name when that is the same release (nothing can be
//!   downloaded here), and only otherwise does rustup install it (stand-in `rustc` and `rustup`);
//! - a run that would fill the disk stops before it starts, naming the figures (stand-in `df` and
//!   `du`: the last CI run ended after 18 minutes with "No space left on device").

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const LIBRARY: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../scripts/lib/install.sh");

/// A folder of stand-in commands and the log they append their calls to.
struct StandIns {
    dir: PathBuf,
}

impl StandIns {
    /// `uid`: what `id -u` answers; `sudo`: whether a `sudo` exists; `removes`: the package a
    /// simulated install reports it would remove (`Remv` line), if any.
    fn new(name: &str, uid: u32, sudo: bool, removes: Option<&str>) -> StandIns {
        let dir = std::env::temp_dir().join(format!("dnet-install-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join("bin")).unwrap();
        let machine = StandIns { dir };
        let stand_in = |command: &str, body: &str| machine.stand_in(command, body);
        stand_in("id", &format!("echo {uid}"));
        let remv = removes.map_or(String::new(), |p| format!("echo 'Remv {p} [1:10.0.2]'"));
        stand_in(
            "apt-get",
            &format!(
                "case \" $* \" in *' -s '*) echo \"Inst ${{@: -1}} (1.0 Debian)\"; {remv};; esac; exit 0"
            ),
        );
        stand_in("apt-cache", "exit 0");
        stand_in("dpkg-query", "exit 1");
        if sudo {
            stand_in("sudo", "shift; exec \"$@\"");
        }
        machine
    }

    /// A stand-in `command` that logs its call and runs `body` (bash).
    fn stand_in(&self, command: &str, body: &str) {
        let path = self.dir.join("bin").join(command);
        let log = self.dir.join("calls.log");
        let script = format!("#!/bin/bash\necho \"{command} $*\" >> '{}'\n{body}\n", log.display());
        std::fs::write(&path, script).unwrap();
        let mut permissions = std::fs::metadata(&path).unwrap().permissions();
        std::os::unix::fs::PermissionsExt::set_mode(&mut permissions, 0o755);
        std::fs::set_permissions(&path, permissions).unwrap();
    }

    /// Runs `script` in bash after sourcing the library, with only the stand-ins and the basic
    /// tools (`/usr/bin/env`, `grep`, `awk`, `tr`, …) on the PATH.
    fn run(&self, script: &str) -> Output {
        let basics = self.dir.join("basics");
        std::fs::create_dir_all(&basics).unwrap();
        for tool in [
            "env", "grep", "awk", "tr", "cat", "printf", "mktemp", "rm", "tail", "sed", "ln", "readlink",
            "dirname", "cut",
        ] {
            let target = ["/usr/bin", "/bin"].iter().map(|d| Path::new(d).join(tool)).find(|p| p.exists());
            let link = basics.join(tool);
            if let (Some(target), false) = (target, link.exists()) {
                std::os::unix::fs::symlink(target, link).unwrap();
            }
        }
        let path = format!("{}:{}", self.dir.join("bin").display(), basics.display());
        Command::new("/bin/bash")
            .arg("-c")
            .arg(format!(". '{LIBRARY}'\n{script}"))
            .env_clear()
            .env("PATH", path)
            .env("HOME", &self.dir)
            .output()
            .expect("bash runs")
    }

    /// The stand-ins' calls, one line each.
    fn calls(&self) -> Vec<String> {
        std::fs::read_to_string(self.dir.join("calls.log"))
            .unwrap_or_default()
            .lines()
            .map(String::from)
            .collect()
    }
}

impl Drop for StandIns {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

fn installs(calls: &[String]) -> Vec<&String> {
    calls
        .iter()
        .filter(|c| c.starts_with("apt-get") && c.contains(" install ") && !c.contains(" -s "))
        .collect()
}

#[test]
fn a_tool_that_is_present_is_not_installed_again() {
    let machine = StandIns::new("present", 0, true, None);
    // `env` is on the PATH: as Node.js from another source would be.
    let output = machine.run("need_command env coreutils && echo done");
    assert_eq!(String::from_utf8_lossy(&output.stdout), "done\n", "{output:?}");
    assert!(machine.calls().iter().all(|c| !c.starts_with("apt-get")), "{:?}", machine.calls());
}

#[test]
fn a_missing_tool_is_installed_alone_as_root() {
    let machine = StandIns::new("root", 0, false, None);
    let output = machine.run("need_command socat socat && need_command npm npm && echo done");
    assert_eq!(String::from_utf8_lossy(&output.stdout), "done\n", "{output:?}");
    let calls = machine.calls();
    let installs = installs(&calls);
    assert_eq!(installs.len(), 2, "{calls:?}");
    assert!(installs[0].ends_with(" socat") && installs[1].ends_with(" npm"), "{calls:?}");
    assert!(installs.iter().all(|c| c.contains("--no-remove")), "{calls:?}");
    assert!(calls.iter().all(|c| !c.starts_with("sudo")), "{calls:?}");
}

#[test]
fn a_package_that_would_remove_one_of_the_machine_s_is_refused_naming_it() {
    let machine = StandIns::new("conflict", 0, false, Some("qemu-utils"));
    let output = machine.run("need_command qemu-system-arm qemu-system-arm || echo refused");
    assert_eq!(String::from_utf8_lossy(&output.stdout), "refused\n", "{output:?}");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("not installing Debian's qemu-system-arm: it would remove qemu-utils"),
        "{stderr}"
    );
    assert!(installs(&machine.calls()).is_empty(), "{:?}", machine.calls());
}

#[test]
fn a_user_who_is_not_root_installs_through_sudo() {
    let machine = StandIns::new("sudo", 1000, true, None);
    let output = machine.run("need_command socat socat && echo done");
    assert_eq!(String::from_utf8_lossy(&output.stdout), "done\n", "{output:?}");
    let calls = machine.calls();
    assert!(
        calls.iter().any(|c| c.starts_with("sudo -- env DEBIAN_FRONTEND=noninteractive apt-get install")),
        "{calls:?}"
    );
}

#[test]
fn a_user_without_root_or_sudo_is_told_what_to_install() {
    let machine = StandIns::new("nosudo", 1000, false, None);
    let output = machine.run("need_command socat socat || echo failed");
    assert_eq!(String::from_utf8_lossy(&output.stdout), "failed\n", "{output:?}");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("cannot install socat: not root and no sudo"), "{stderr}");
    assert!(stderr.contains("apt-get install socat"), "{stderr}");
    assert!(installs(&machine.calls()).is_empty(), "{:?}", machine.calls());
}

/// A machine whose stable rustc is `stable` and whose rustup lists `listed` toolchains, with the
/// pin of `rust-toolchain.toml` at 1.95.0; runs `need_rust_toolchain` in that folder.
fn pinned_toolchain(name: &str, stable: &str, listed: &[&str]) -> (StandIns, Output) {
    let machine = StandIns::new(name, 0, false, None);
    let home = machine.dir.join("rustup");
    std::fs::create_dir_all(home.join("toolchains/stable-x86_64-unknown-linux-gnu")).unwrap();
    std::fs::write(machine.dir.join("rust-toolchain.toml"), "[toolchain]\nchannel = \"1.95.0\"\n").unwrap();
    machine.stand_in(
        "rustc",
        &format!(
            "case \"$1\" in -vV) printf 'rustc {stable} (0 2026-01-01)\\nhost: x86_64-unknown-linux-gnu\\n';; \
             -V) echo 'rustc {stable} (0 2026-01-01)';; esac"
        ),
    );
    let list: String = listed.iter().map(|t| format!("echo '{t}'; ")).collect();
    machine.stand_in(
        "rustup",
        &format!(
            "case \"$1 $2\" in 'toolchain list') {list}:;; 'show home') echo '{}';; esac; exit 0",
            home.display()
        ),
    );
    let output = machine.run(&format!("cd '{}' && need_rust_toolchain && echo done", machine.dir.display()));
    (machine, output)
}

#[test]
fn a_pinned_toolchain_rustup_has_is_used_as_it_is() {
    let (machine, output) = pinned_toolchain(
        "pin-present",
        "1.96.0",
        &["stable-x86_64-unknown-linux-gnu (default)", "1.95.0-x86_64-unknown-linux-gnu"],
    );
    assert_eq!(String::from_utf8_lossy(&output.stdout), "done\n", "{output:?}");
    assert!(
        machine.calls().iter().all(|c| !c.starts_with("rustup toolchain install")),
        "{:?}",
        machine.calls()
    );
    assert!(!machine.dir.join("rustup/toolchains/1.95.0-x86_64-unknown-linux-gnu").exists());
}

#[test]
fn stable_of_the_pinned_release_is_linked_under_its_name_not_downloaded() {
    let (machine, output) =
        pinned_toolchain("pin-link", "1.95.0", &["stable-x86_64-unknown-linux-gnu (default)"]);
    assert_eq!(String::from_utf8_lossy(&output.stdout), "done\n", "{output:?}");
    let link = machine.dir.join("rustup/toolchains/1.95.0-x86_64-unknown-linux-gnu");
    assert_eq!(
        std::fs::read_link(&link).unwrap(),
        machine.dir.join("rustup/toolchains/stable-x86_64-unknown-linux-gnu")
    );
    assert!(
        machine.calls().iter().all(|c| !c.starts_with("rustup toolchain install")),
        "{:?}",
        machine.calls()
    );
}

#[test]
fn another_stable_release_has_rustup_install_the_pinned_one() {
    let (machine, output) =
        pinned_toolchain("pin-install", "1.96.0", &["stable-x86_64-unknown-linux-gnu (default)"]);
    assert_eq!(String::from_utf8_lossy(&output.stdout), "done\n", "{output:?}");
    let calls = machine.calls();
    assert!(calls.iter().any(|c| c == "rustup toolchain install 1.95.0 --profile minimal"), "{calls:?}");
    assert!(!machine.dir.join("rustup/toolchains/1.95.0-x86_64-unknown-linux-gnu").exists());
}

/// A machine whose file system has `free_gb` free and whose `target` holds `used_gb` (stand-in `df`
/// and `du`, in KiB as theirs print); runs `need_free_space target 20`.
fn free_space(name: &str, free_gb: u64, used_gb: Option<u64>) -> (StandIns, Output) {
    let machine = StandIns::new(name, 0, false, None);
    let kib = |gb: u64| gb * 1024 * 1024;
    machine.stand_in(
        "df",
        &format!(
            "echo 'Filesystem 1024-blocks Used Available Capacity Mounted on'\necho '/dev/vda 264241152 1 {} 90% /'",
            kib(free_gb)
        ),
    );
    machine.stand_in("du", &format!("printf '%s\\t%s\\n' {} \"$2\"", kib(used_gb.unwrap_or(0))));
    if used_gb.is_some() {
        std::fs::create_dir_all(machine.dir.join("target")).unwrap();
    }
    let output =
        machine.run(&format!("cd '{}' && need_free_space target 20 && echo done", machine.dir.display()));
    (machine, output)
}

#[test]
fn a_disk_with_room_for_the_run_passes() {
    let (_machine, output) = free_space("room", 25, None);
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    assert_eq!(String::from_utf8_lossy(&output.stdout).trim(), "done");
}

#[test]
fn a_disk_without_room_stops_the_run_naming_the_figures() {
    let (_machine, output) = free_space("full", 9, None);
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("not enough disk space")
            && stderr.contains("about 20 GB under target")
            && stderr.contains("9 GB free")
            && stderr.contains("Free 11 GB more"),
        "{stderr}"
    );
}

#[test]
fn what_target_already_holds_counts_toward_the_need() {
    // A second run in the same tree rebuilds in place: 9 GB free and 15 GB already there is enough.
    let (machine, output) = free_space("rerun", 9, Some(15));
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    assert!(machine.calls().iter().any(|c| c.starts_with("du ")), "{:?}", machine.calls());
}
