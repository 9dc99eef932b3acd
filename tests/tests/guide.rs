//! The user guide (`docs/`, an mdBook) and the README that leads into it.
//!
//! - `readme_is_a_front_door`: the README is at most 200 lines, its layout table has a row for
//!   every workspace member, and every relative link in it names a file of the repository.
//! - `cli_reference_is_current` (ignored: needs the programs built, `cargo build --bins`): every
//!   command's `--help` of `dnet-master`, `dnet-eds`, `dnet-soft-slave` and `dnet-sim-breaker`,
//!   found by walking each program's `Commands:` lists, rendered into `docs/src/reference/cli.md`
//!   and compared with the committed page; `UPDATE_GUIDE=1` rewrites the page instead. The page is
//!   taken from the built programs' own help, so it cannot drift from their options, wherever
//!   their code lives.
//! - `book_builds_and_its_links_resolve` (ignored: needs `mdbook` on `PATH`): `mdbook build docs`
//!   into a scratch folder, no warning or error from mdBook, then every `href` and `src` of every
//!   chapter page checked: the file exists, and a `#fragment` is an `id` of the page it points at.
//!
//! - `every_page_is_in_the_summary`: mdBook renders only what SUMMARY.md lists.
//! - `the_paths_the_guide_names_exist`: every repository path the README and the guide name in a
//!   code span exists.
//! - `mdbook_is_installed_only_when_missing_and_outside_the_workspace`: the book's install step
//!   (`need_cargo_tool` of `scripts/lib/install.sh`) against a stand-in `cargo`.
//! - `the_framed_example_is_the_reference_breaker`: the description file's page writes the breaker
//!   out as a framed instrument, key by key; that block loads and describes the reference device.
//!
//! Both ignored tests run in the `./scripts/check` stage "the user guide".

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Component, Path, PathBuf};
use std::process::Command;

const ROOT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/..");
const CLI_PAGE: &str = "docs/src/reference/cli.md";
const README_MAX_LINES: usize = 200;
/// The programs of the reference, in the order the page shows them.
const PROGRAMS: [&str; 4] = ["dnet-master", "dnet-eds", "dnet-soft-slave", "dnet-sim-breaker"];

fn root() -> PathBuf {
    PathBuf::from(ROOT)
}

// ---- the README ------------------------------------------------------------------------------

#[test]
fn readme_is_a_front_door() {
    let readme = std::fs::read_to_string(root().join("README.md")).expect("README.md");
    let lines = readme.lines().count();
    assert!(
        lines <= README_MAX_LINES,
        "README.md has {lines} lines; at most {README_MAX_LINES}: move the rest into the guide (docs/src/)"
    );
    let cargo = std::fs::read_to_string(root().join("Cargo.toml")).expect("Cargo.toml");
    let members = cargo.lines().find_map(|l| l.strip_prefix("members = [")).expect("the workspace's members");
    let unlisted: Vec<&str> = members
        .split('"')
        .skip(1)
        .step_by(2)
        .filter(|member| !readme.contains(&format!("| `{member}/` |")))
        .collect();
    assert!(members.contains('"'), "no member found in Cargo.toml's members line");
    assert!(
        unlisted.is_empty(),
        "the README's layout table has no row for the workspace members {unlisted:?}"
    );
    let links = markdown_links(&readme);
    assert!(!links.is_empty(), "the README links into the guide, yet no link was found in it");
    let missing: Vec<_> = links
        .iter()
        .filter(|l| is_relative(l))
        .map(|l| l.split('#').next().unwrap_or(l))
        .filter(|path| !root().join(path).exists())
        .collect();
    assert!(missing.is_empty(), "README.md links to files that do not exist: {missing:?}");
}

/// The targets of the Markdown links `[text](target)` and images `![alt](target)` in `text`,
/// outside fenced code blocks.
fn markdown_links(text: &str) -> Vec<String> {
    let mut links = Vec::new();
    let mut fenced = false;
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            continue;
        }
        if fenced {
            continue;
        }
        let mut rest = line;
        while let Some(at) = rest.find("](") {
            let after = &rest[at + 2..];
            let Some(end) = after.find(')') else { break };
            links.push(after[..end].to_string());
            rest = &after[end..];
        }
    }
    links
}

/// `true` for a link into the repository or the book (not a URL, not a bare `#fragment`).
fn is_relative(link: &str) -> bool {
    !(link.is_empty() || link.starts_with('#') || link.starts_with("//") || has_scheme(link))
}

/// `true` when `link` starts with a URL scheme (`https:`, `mailto:`, `data:`, ...).
fn has_scheme(link: &str) -> bool {
    match link.find(':') {
        Some(colon) => {
            link[..colon].chars().all(|c| c.is_ascii_alphanumeric() || "+-.".contains(c)) && colon > 0
        }
        None => false,
    }
}

// ---- paths the guide names --------------------------------------------------------------------

/// Every repository path the README and the guide name in code spans (`scanner/src/history.rs`,
/// `slave-fw/descriptions/`) exists: files move, and a guide that sends its reader to a file that
/// is gone is not true.
#[test]
fn the_paths_the_guide_names_exist() {
    let top: BTreeSet<String> = std::fs::read_dir(root())
        .expect("the repository")
        .flatten()
        .filter(|e| e.path().is_dir())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|name| !name.starts_with('.') && name != "target")
        .collect();
    let mut pages = vec![root().join("README.md")];
    collect_markdown(&root().join("docs/src"), &mut pages);
    let (mut checked, mut missing) = (0, Vec::new());
    for page in &pages {
        let text = std::fs::read_to_string(page).expect("a page");
        for span in prose(&text).split('`').skip(1).step_by(2) {
            let path = span.trim_end_matches('/');
            let first = path.split('/').next().unwrap_or_default();
            let plain = path.chars().all(|c| c.is_ascii_alphanumeric() || "_-./".contains(c));
            // `fuzz/artifacts/TARGET/`: a placeholder, not a path.
            let placeholder =
                path.split('/').any(|c| !c.is_empty() && c.chars().all(|c| c.is_ascii_uppercase()));
            if !plain || placeholder || !path.contains('/') || !top.contains(first) {
                continue;
            }
            checked += 1;
            if !root().join(path).exists() {
                missing.push(format!("{}: {span}", page.strip_prefix(root()).unwrap_or(page).display()));
            }
        }
    }
    assert!(checked > 50, "only {checked} repository paths found in the guide: is it there?");
    assert!(missing.is_empty(), "the guide names paths that do not exist:\n{}", missing.join("\n"));
}

/// `text` without its fenced code blocks.
fn prose(text: &str) -> String {
    let mut fenced = false;
    let mut out = String::new();
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
        } else if !fenced {
            out.push_str(line);
            out.push('\n');
        }
    }
    out
}

/// The Markdown files under `dir`, but the protocol reference's (written from its own sources) and
/// the generated CLI reference.
fn collect_markdown(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).expect("a folder of the guide").flatten() {
        let path = entry.path();
        if path.is_dir() && !path.ends_with("protocol") {
            collect_markdown(&path, out);
        } else if path.extension().is_some_and(|e| e == "md") && !path.ends_with("reference/cli.md") {
            out.push(path);
        }
    }
}

/// Every page under `docs/src/` is a chapter of SUMMARY.md: mdBook renders only the pages listed
/// there, so a page left out would be missing from the book without a word.
#[test]
fn every_page_is_in_the_summary() {
    let src = root().join("docs/src");
    let summary = std::fs::read_to_string(src.join("SUMMARY.md")).expect("docs/src/SUMMARY.md");
    let listed: BTreeSet<String> = markdown_links(&summary).into_iter().collect();
    let mut pages = Vec::new();
    collect_all_markdown(&src, &mut pages);
    let unlisted: Vec<String> = pages
        .iter()
        .map(|p| p.strip_prefix(&src).unwrap_or(p).to_string_lossy().into_owned())
        .filter(|p| p != "SUMMARY.md" && !listed.contains(p))
        .collect();
    assert!(pages.len() > 40, "only {} pages under docs/src", pages.len());
    assert!(unlisted.is_empty(), "pages missing from docs/src/SUMMARY.md: {unlisted:?}");
}

fn collect_all_markdown(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).expect("a folder of the guide").flatten() {
        let path = entry.path();
        if path.is_dir() {
            collect_all_markdown(&path, out);
        } else if path.extension().is_some_and(|e| e == "md") {
            out.push(path);
        }
    }
}

// ---- the CLI reference -----------------------------------------------------------------------

/// The folder of the workspace's programs: `DNET_BIN_DIR`, else next to this test's `deps/`.
fn bin_dir() -> PathBuf {
    if let Some(d) = std::env::var_os("DNET_BIN_DIR") {
        return PathBuf::from(d);
    }
    let exe = std::env::current_exe().expect("the test's own path");
    exe.parent().and_then(Path::parent).expect("target/<profile>/deps/<test>").to_path_buf()
}

/// `program args... --help`, its standard output; fails the test when the program is missing or
/// its help fails.
fn help(program: &Path, args: &[String]) -> String {
    let out = Command::new(program)
        .args(args)
        .arg("--help")
        .env("COLUMNS", "100")
        .output()
        .unwrap_or_else(|e| panic!("{} cannot be run: {e}", program.display()));
    assert!(
        out.status.success(),
        "{} {} --help failed ({}): {}",
        program.display(),
        args.join(" "),
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).expect("help is UTF-8")
}

/// The subcommands a clap help lists under `Commands:` (without `help`).
fn subcommands(help: &str) -> Vec<String> {
    let mut names = Vec::new();
    let mut listing = false;
    for line in help.lines() {
        if line == "Commands:" {
            listing = true;
        } else if listing {
            match line.strip_prefix("  ").and_then(|l| l.split_whitespace().next()) {
                Some(name) if !line.starts_with("   ") => {
                    if name != "help" {
                        names.push(name.to_string());
                    }
                }
                Some(_) => {} // a wrapped description
                None => listing = false,
            }
        }
    }
    names
}

/// The reference page: every command of every program, each with its help as the program prints it.
fn render_cli_reference(programs: &[(&str, PathBuf)]) -> String {
    let mut page = String::from(
        "# Command-line reference\n\n\
         <!-- Generated by tests/tests/guide.rs from the programs' own --help; do not edit.\n     \
         After a change to a program's options: cargo build --bins && \
         UPDATE_GUIDE=1 cargo test -p system-tests --test guide -- --ignored -->\n\n\
         Every command and option of the project's programs, as their `--help` prints them. The\n\
         programs' exit status is the same for all: [Exit status](exit-status.md).\n",
    );
    for (name, path) in programs {
        // (heading depth, argument path) in the order the help lists them.
        let mut queue = vec![(2usize, Vec::<String>::new())];
        while let Some((depth, args)) = queue.pop() {
            let text = help(path, &args);
            let title =
                std::iter::once(name.to_string()).chain(args.iter().cloned()).collect::<Vec<_>>().join(" ");
            page.push_str(&format!("\n{} {title}\n\n```text\n{}\n```\n", "#".repeat(depth), text.trim_end()));
            let subs = subcommands(&text);
            for sub in subs.into_iter().rev() {
                let mut next = args.clone();
                next.push(sub);
                queue.push(((depth + 1).min(6), next));
            }
        }
    }
    page
}

#[test]
#[ignore = "needs the programs built (cargo build --bins); scripts/check stage \"the user guide\""]
fn cli_reference_is_current() {
    let dir = bin_dir();
    let programs: Vec<(&str, PathBuf)> = PROGRAMS
        .iter()
        .map(|name| {
            let path = dir.join(name);
            assert!(
                path.is_file(),
                "{} is not built: cargo build --bins (or set DNET_BIN_DIR)",
                path.display()
            );
            (*name, path)
        })
        .collect();
    let rendered = render_cli_reference(&programs);
    for (name, _) in &programs {
        assert!(rendered.contains(&format!("\n## {name}\n")), "the reference has no section for {name}");
    }
    let page = root().join(CLI_PAGE);
    if std::env::var_os("UPDATE_GUIDE").is_some() {
        std::fs::write(&page, &rendered).expect("write the CLI reference");
        return;
    }
    let committed = std::fs::read_to_string(&page).unwrap_or_default();
    if committed != rendered {
        let first = committed.lines().zip(rendered.lines()).position(|(a, b)| a != b);
        let line = first.unwrap_or(committed.lines().count().min(rendered.lines().count()));
        panic!(
            "{CLI_PAGE} is out of date (first difference at line {}: committed {:?}, programs {:?}); \
             rewrite it with UPDATE_GUIDE=1 cargo test -p system-tests --test guide -- --ignored",
            line + 1,
            committed.lines().nth(line),
            rendered.lines().nth(line)
        );
    }
}

#[test]
fn subcommands_are_read_from_the_commands_list() {
    let text = "About\n\nUsage: x <COMMAND>\n\nCommands:\n  connect  Bring up\n  set-it   Set\n           \
                wrapped text\n  help     Print this message\n\nOptions:\n  -h, --help  Print help\n";
    assert_eq!(subcommands(text), ["connect", "set-it"]);
    assert!(subcommands("Usage: x [OPTIONS]\n\nOptions:\n  -h, --help  Print help\n").is_empty());
}

// ---- the book's install step ------------------------------------------------------------------

/// `need_cargo_tool` (scripts/lib/install.sh), run with a stand-in `cargo` that records its
/// arguments and folder: what `cargo install` was asked, or nothing.
fn need_cargo_tool(tool_present: bool) -> Vec<String> {
    let dir = std::env::var_os("CARGO_TARGET_TMPDIR")
        .map(PathBuf::from)
        .unwrap_or_else(std::env::temp_dir)
        .join(format!("guide-install-{tool_present}"));
    let _ = std::fs::remove_dir_all(&dir);
    let bin = dir.join("bin");
    std::fs::create_dir_all(&bin).unwrap();
    let log = dir.join("calls");
    let stand_in = |name: &str, body: &str| {
        let path = bin.join(name);
        std::fs::write(&path, format!("#!/bin/sh\n{body}\n")).unwrap();
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o755)).unwrap();
    };
    stand_in("cargo", &format!("echo \"$(pwd) $*\" >> {}", log.display()));
    if tool_present {
        stand_in("mdbook", "exit 0");
    }
    let script = format!(
        ". {}/scripts/lib/install.sh && need_cargo_tool mdbook mdbook 0.5.4 --no-default-features --features search",
        root().display()
    );
    // Only the stand-ins on PATH: an mdbook the machine has elsewhere must not count.
    let out = Command::new("/bin/bash")
        .arg("-c")
        .arg(script)
        .env("PATH", &bin)
        .env("TMPDIR", &dir)
        .output()
        .expect("bash");
    assert!(out.status.success(), "need_cargo_tool failed: {}", String::from_utf8_lossy(&out.stderr));
    std::fs::read_to_string(&log)
        .unwrap_or_default()
        .lines()
        .map(|l| l.replace(&dir.display().to_string(), "TMP"))
        .collect()
}

#[test]
fn mdbook_is_installed_only_when_missing_and_outside_the_workspace() {
    assert_eq!(need_cargo_tool(true), Vec::<String>::new(), "mdbook is there: nothing to install");
    assert_eq!(
        need_cargo_tool(false),
        ["TMP install --locked --quiet mdbook --version 0.5.4 --no-default-features --features search"]
    );
}

// ---- the book's links ------------------------------------------------------------------------

/// A link of the built book that does not resolve.
#[derive(Debug, PartialEq, Eq, PartialOrd, Ord)]
struct BrokenLink {
    /// The page it is on, relative to the book's folder.
    page: String,
    /// The link as written.
    link: String,
    /// What is wrong.
    why: &'static str,
}

/// Pages mdBook writes for its own machinery, whose links are not the chapters' (the print page
/// rewrites every chapter link to an anchor of its own; the 404 page sets a site-root base).
const MACHINERY: [&str; 3] = ["print.html", "toc.html", "404.html"];

/// Checks every `href` and `src` of every chapter page under `book`: the file exists and a
/// `#fragment` is an `id` (or `name`) of the page it points at. Returns the number of links
/// checked and the broken ones.
fn check_book_links(book: &Path) -> (usize, Vec<BrokenLink>) {
    let mut pages = Vec::new();
    collect_html(book, &mut pages);
    let mut ids: BTreeMap<PathBuf, BTreeSet<String>> = BTreeMap::new();
    let mut ids_of = |path: &Path| -> BTreeSet<String> {
        ids.entry(path.to_path_buf())
            .or_insert_with(|| {
                let text = std::fs::read_to_string(path).unwrap_or_default();
                let mut found = attribute_values(&text, "id");
                found.extend(attribute_values(&text, "name"));
                found.into_iter().collect()
            })
            .clone()
    };
    let (mut checked, mut broken) = (0, Vec::new());
    for page in pages {
        let rel = page.strip_prefix(book).unwrap_or(&page).to_string_lossy().into_owned();
        if MACHINERY.contains(&rel.as_str()) {
            continue;
        }
        let text = std::fs::read_to_string(&page).expect("a page of the book");
        let mut links = attribute_values(&text, "href");
        links.extend(attribute_values(&text, "src"));
        for link in links {
            if link.is_empty() || link.starts_with("//") || has_scheme(&link) {
                continue;
            }
            checked += 1;
            let (path, fragment) = match link.split_once('#') {
                Some((p, f)) => (p, Some(f)),
                None => (link.as_str(), None),
            };
            let path = path.split('?').next().unwrap_or(path);
            let target = if path.is_empty() {
                page.clone()
            } else {
                let mut t = normalize(&page.parent().unwrap_or(book).join(path));
                if path.ends_with('/') {
                    t.push("index.html");
                }
                t
            };
            if !target.starts_with(book) || !target.is_file() {
                broken.push(BrokenLink { page: rel.clone(), link, why: "no such file in the book" });
                continue;
            }
            if let Some(fragment) = fragment.filter(|f| !f.is_empty()) {
                let is_html = target.extension().is_some_and(|e| e == "html");
                if is_html && !ids_of(&target).contains(fragment) {
                    broken.push(BrokenLink { page: rel.clone(), link, why: "no such anchor on that page" });
                }
            }
        }
    }
    broken.sort();
    (checked, broken)
}

fn collect_html(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).expect("a folder of the book").flatten() {
        let path = entry.path();
        if path.is_dir() {
            collect_html(&path, out);
        } else if path.extension().is_some_and(|e| e == "html") {
            out.push(path);
        }
    }
    out.sort();
}

/// `path` with `.` and `..` resolved lexically.
fn normalize(path: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in path.components() {
        match c {
            Component::ParentDir => {
                out.pop();
            }
            Component::CurDir => {}
            other => out.push(other),
        }
    }
    out
}

/// The values of every `NAME="..."` attribute in `html` (entities `&amp;`, `&quot;` decoded),
/// outside `<script>` elements.
fn attribute_values(html: &str, name: &str) -> Vec<String> {
    let mut values = Vec::new();
    let pattern = format!(" {name}=\"");
    let mut rest = html;
    while let Some(at) = rest.find(&pattern) {
        let before = &rest[..at];
        // Skip the inside of a script element: its text is code, not markup.
        if let Some(open) = before.rfind("<script") {
            if before[open..].find("</script>").is_none() {
                rest = match rest[at..].find("</script>") {
                    Some(end) => &rest[at + end..],
                    None => "",
                };
                continue;
            }
        }
        let after = &rest[at + pattern.len()..];
        let Some(end) = after.find('"') else { break };
        values.push(after[..end].replace("&quot;", "\"").replace("&amp;", "&"));
        rest = &after[end..];
    }
    values
}

#[test]
#[ignore = "needs mdbook on PATH; scripts/check stage \"the user guide\""]
fn book_builds_and_its_links_resolve() {
    let out_dir = std::env::var_os("CARGO_TARGET_TMPDIR")
        .map(PathBuf::from)
        .unwrap_or_else(std::env::temp_dir)
        .join("guide-book");
    let _ = std::fs::remove_dir_all(&out_dir);
    let built = Command::new("mdbook")
        .arg("build")
        .arg(root().join("docs"))
        .arg("--dest-dir")
        .arg(&out_dir)
        .output()
        .unwrap_or_else(|e| {
            panic!("mdbook cannot be run ({e}): cargo install --locked mdbook (scripts/check installs it)")
        });
    let log = String::from_utf8_lossy(&built.stderr);
    assert!(built.status.success(), "mdbook build docs failed:\n{log}");
    let complaints: Vec<&str> = log.lines().filter(|l| l.contains("WARN") || l.contains("ERROR")).collect();
    assert!(complaints.is_empty(), "mdbook build docs complained:\n{}", complaints.join("\n"));
    let (checked, broken) = check_book_links(&out_dir);
    assert!(checked > 100, "only {checked} links were checked in {}: is the book there?", out_dir.display());
    assert!(
        broken.is_empty(),
        "{} of {checked} links of the book do not resolve:\n{broken:#?}",
        broken.len()
    );
}

/// The checker itself: a small book with one link of each kind, good and broken.
#[test]
fn the_link_checker_finds_broken_links() {
    let dir = std::env::var_os("CARGO_TARGET_TMPDIR")
        .map(PathBuf::from)
        .unwrap_or_else(std::env::temp_dir)
        .join("guide-links-self-test");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("part")).unwrap();
    std::fs::create_dir_all(dir.join("images")).unwrap();
    std::fs::write(dir.join("images/a.png"), b"png").unwrap();
    std::fs::write(
        dir.join("index.html"),
        "<h2 id=\"top\">t</h2><a href=\"part/page.html#s7-1\">ok</a> <a href=\"part/page.html#s7-9\">bad anchor</a>\n\
         <a href=\"missing.html\">bad file</a> <img src=\"images/a.png\"> <img src=\"images/b.png\">\n\
         <a href=\"#top\">ok</a> <a href=\"https://example.invalid/x\">external</a>\n\
         <script>var x = ' href=\"nowhere.html\"';</script>",
    )
    .unwrap();
    std::fs::write(dir.join("part/page.html"), "<h3 id=\"s7-1\">x</h3><a href=\"../index.html#top\">ok</a>")
        .unwrap();
    std::fs::write(dir.join("print.html"), "<a href=\"not-checked.html\">machinery</a>").unwrap();
    let (checked, broken) = check_book_links(&dir);
    let found: Vec<(&str, &str)> = broken.iter().map(|b| (b.link.as_str(), b.why)).collect();
    assert_eq!(
        found,
        [
            ("images/b.png", "no such file in the book"),
            ("missing.html", "no such file in the book"),
            ("part/page.html#s7-9", "no such anchor on that page"),
        ]
    );
    assert_eq!(checked, 7, "{broken:?}");
}

// ---- the description file's framed example -----------------------------------------------------

/// The framed example of the description file's page is the breaker written out key by key: it
/// loads, and it describes exactly the built-in reference device (so every key and value shown is
/// one the loader takes, with the meaning the page gives it).
#[test]
fn the_framed_example_is_the_reference_breaker() {
    use slave_fw::description::DeviceDescription;
    let page =
        std::fs::read_to_string(root().join("docs/src/reference/description-file.md")).expect("the page");
    let blocks: Vec<&str> = page.split("```toml\n").skip(1).filter_map(|b| b.split("```").next()).collect();
    let framed: Vec<&&str> = blocks.iter().filter(|b| b.contains("kind = \"framed\"")).collect();
    assert_eq!(
        framed.len(),
        1,
        "the page has one framed example, found {} among {} TOML blocks",
        framed.len(),
        blocks.len()
    );
    let loaded = DeviceDescription::parse(framed[0])
        .unwrap_or_else(|e| panic!("the framed example does not load: {e}"));
    assert_eq!(loaded, DeviceDescription::reference(), "the framed example is not the reference breaker");
}
