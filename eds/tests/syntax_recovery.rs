//! One mistake, one error: every closing quote and every `;` of the vendor files in
//! `../shared/eds-corpus/` is removed in turn, and the checker must report exactly one syntax
//! error, at the right place, with no cascade.

use eds::{check_str, Diagnostic, Rule, Span};

const FILES: [&str; 3] = [
    concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/eds-corpus/hilscher_netx90_dns.eds"),
    concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/eds-corpus/hilscher_dns_v5_simple.eds"),
    concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/eds-corpus/hilscher_dns_v5_extended.eds"),
];

fn syntax_errors(text: &str) -> Vec<Diagnostic> {
    check_str(text).diagnostics.into_iter().filter(|d| d.rule == Rule::Syntax).collect()
}

/// `text` without the character at byte `at`.
fn without(text: &str, at: usize) -> String {
    let mut out = text.to_string();
    out.remove(at);
    out
}

/// The code part of a line (before a `$` comment; the vendor files have no `$` in strings).
fn code(line: &str) -> &str {
    line.split('$').next().unwrap_or(line)
}

#[test]
fn a_missing_closing_quote_is_one_error_at_its_opening_quote() {
    let mut cases = 0;
    for path in FILES {
        let text = std::fs::read_to_string(path).unwrap();
        let mut offset = 0;
        for (index, line) in text.split_inclusive('\n').enumerate() {
            let quotes: Vec<usize> = code(line).match_indices('"').map(|(i, _)| i).collect();
            // Each string's closing quote (odd positions), one at a time.
            for pair in quotes.chunks(2).filter(|p| p.len() == 2) {
                let (open, close) = (pair[0], pair[1]);
                let broken = without(&text, offset + close);
                let line_no = u32::try_from(index + 1).unwrap();
                let column = u32::try_from(line[..open].chars().count() + 1).unwrap();
                let errors = syntax_errors(&broken);
                let messages: Vec<String> =
                    errors.iter().map(|d| format!("{}: {}", d.span, d.message)).collect();
                assert_eq!(
                    messages,
                    [format!(
                        "{line_no}:{column}: string is not terminated: the '\"' here has no closing '\"'"
                    )],
                    "{path}: closing quote of line {line_no} removed"
                );
                cases += 1;
            }
            offset += line.len();
        }
    }
    assert!(cases > 70, "only {cases} strings");
}

#[test]
fn a_missing_semicolon_is_one_error_after_the_entry_that_lacks_it() {
    let mut cases = 0;
    for path in FILES {
        let text = std::fs::read_to_string(path).unwrap();
        let mut offset = 0;
        let mut keyword = String::new();
        for (index, line) in text.split_inclusive('\n').enumerate() {
            let code = code(line);
            if let Some((key, _)) = code.split_once('=') {
                keyword = key.trim().to_string();
            }
            if let Some(at) = code.find(';') {
                let broken = without(&text, offset + at);
                let span = Span::new(
                    u32::try_from(index + 1).unwrap(),
                    u32::try_from(line[..at].chars().count() + 1).unwrap(),
                );
                let errors = syntax_errors(&broken);
                let messages: Vec<String> =
                    errors.iter().map(|d| format!("{}: {}", d.span, d.message)).collect();
                assert_eq!(
                    messages,
                    [format!("{span}: missing ';' after entry `{keyword}`")],
                    "{path}: ';' of line {} removed",
                    span.line
                );
                cases += 1;
            }
            offset += line.len();
        }
    }
    assert!(cases >= 100, "only {cases} entries");
}

#[test]
fn the_checker_prints_file_line_column_and_rule() {
    let text = "[File]\n        DescText = \"no end;\n        Revision = 1.0;\n";
    let mut report = check_str(text);
    report.file = Some("broken.eds".into());
    let printed = report.to_string();
    let syntax: Vec<&str> = printed.lines().filter(|l| l.contains("error[syntax]")).collect();
    assert_eq!(
        syntax,
        ["broken.eds:2:20: error[syntax]: string is not terminated: the '\"' here has no closing '\"'"],
        "{printed}"
    );
}
