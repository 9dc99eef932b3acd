//! `dnet-eds format` ([`eds::format`]) on real and hand-made files: the output reads back to the
//! same model, formatting it again changes nothing, the vendor's `$` comments stay beside what
//! they describe, and a Latin-1 file's bytes 0x80–0xFF come back unchanged.

use eds::comments::Comments;
use eds::text::decode;
use eds::RawEds;
use std::path::{Path, PathBuf};

const SHARED_CORPUS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/eds-corpus");
const EXTENDED: &str =
    concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/eds-corpus/hilscher_dns_v5_extended.eds");

/// Every `.eds` file of the shared vendor corpus and of the project's test corpus that parses.
fn corpus_files() -> Vec<PathBuf> {
    let local = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/corpus");
    let mut files = Vec::new();
    for dir in [Path::new(SHARED_CORPUS), local.as_path()] {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "eds") && eds::read_file(&path).is_ok() {
                files.push(path);
            }
        }
    }
    files.sort();
    files
}

fn comments(bytes: &[u8]) -> Comments {
    let (text, _) = decode(bytes).unwrap();
    RawEds::parse_with_comments(&text).unwrap().1
}

fn format(bytes: &[u8]) -> Vec<u8> {
    eds::format(bytes).unwrap()
}

/// The model as JSON without source positions: entries the model keeps untyped (`other`) carry
/// the line and column they were read at, which the writer's layout changes.
fn model(bytes: &[u8]) -> serde_json::Value {
    fn strip(value: &mut serde_json::Value) {
        match value {
            serde_json::Value::Object(map) => {
                map.remove("span");
                map.values_mut().for_each(strip);
            }
            serde_json::Value::Array(items) => items.iter_mut().for_each(strip),
            _ => {}
        }
    }
    let mut value = serde_json::to_value(eds::parse(bytes).unwrap()).unwrap();
    strip(&mut value);
    value
}

#[test]
fn every_corpus_file_formats_to_the_same_model_and_a_fixed_point() {
    let files = corpus_files();
    assert!(files.len() >= 10, "corpus files found: {files:?}");
    assert!(files.iter().any(|f| f.ends_with("hilscher_dns_v5_extended.eds")), "{files:?}");
    for path in files {
        let name = path.display();
        let bytes = std::fs::read(&path).unwrap();
        let once = format(&bytes);
        assert_eq!(model(&once), model(&bytes), "{name}: model changed");
        let twice = format(&once);
        assert!(
            once == twice,
            "{name}: format is not a fixed point\n--- once\n{}\n--- twice\n{}",
            String::from_utf8_lossy(&once),
            String::from_utf8_lossy(&twice)
        );
    }
}

#[test]
fn every_corpus_comment_is_kept_beside_its_item() {
    for path in corpus_files() {
        let name = path.display();
        let bytes = std::fs::read(&path).unwrap();
        let before = comments(&bytes);
        let after = comments(&format(&bytes));
        assert_eq!(after.header, before.header, "{name}: header");
        assert_eq!(after.sections, before.sections, "{name}: section comments");
        // Comments of entries the model ignores (a repeated keyword) go above the trailer.
        let mut moved: Vec<String> = Vec::new();
        for (key, attached) in &before.entries {
            let Some(kept) = after.entries.get(key) else {
                moved.extend(attached.before.iter().filter(|l| !l.is_empty()).cloned());
                moved.extend(attached.end_of_line.iter().cloned());
                moved.extend(attached.fields.values().flatten().cloned());
                continue;
            };
            assert_eq!(kept.before, attached.before, "{name}: comments above {key:?}");
            // A single-line output entry carries its field comments at its end of line.
            if kept.fields.is_empty() && !attached.fields.is_empty() {
                let all: Vec<&String> =
                    attached.end_of_line.iter().chain(attached.fields.values().flatten()).collect();
                let joined = all.iter().map(|s| s.as_str()).collect::<Vec<_>>().join(" ");
                assert_eq!(kept.end_of_line.as_deref(), Some(joined.as_str()), "{name}: {key:?}");
            } else {
                assert_eq!(kept.end_of_line, attached.end_of_line, "{name}: end of line of {key:?}");
                for (field, texts) in &attached.fields {
                    assert_eq!(kept.fields.get(field), Some(texts), "{name}: field {field} of {key:?}");
                }
            }
        }
        let mut trailer = moved;
        if !trailer.is_empty() && !before.trailer.is_empty() {
            trailer.push(String::new());
        }
        trailer.extend(before.trailer.iter().cloned());
        assert_eq!(after.trailer, trailer, "{name}: trailer");
    }
}

#[test]
fn hilscher_notice_and_section_comments_stay_in_place() {
    let text = String::from_utf8(format(&std::fs::read(EXTENDED).unwrap())).unwrap();
    let notice = "$ EZ-EDS Version 3.27.1.20191218 Generated Electronic Data Sheet

$ DNS V5 Extended Configuration Demo Electronic Data Sheet
$ Version 1.1
$ 01/01/21
$ Template EDS file provided by Hilscher Gesellschaft fuer Systemautomation mbH
$ Template fingerprint: $Id: $
$ Please provide the above fingerprint for reference in any support requests towards Hilscher.
$
$ This file should be changed by the device manufacturer only.
$ Incompatible changes may lead to communication errors in the DeviceNet network
$
$ The metafields ModDate and ModTime in section [File] are set to arbitrary values in this template.
$ The customer will have to modify these in the development process along with the actual content.

$ File Description Section
[File]
";
    assert!(text.starts_with(notice), "{text}");
    for expected in [
        "\n\n$ Device Description Section\n[Device]\n",
        "\n\n$ I/O Characteristics Section\n[IO_Info]\n",
        "\n        Default = 0x0001;                 $ poll as default\n",
        "\n        PollInfo =\n                0x000F,                   $ OK to Combine w/Poll/Strobe/COS/Cyclic\n",
        "\n                1;                        $ Default Output = Output1\n",
    ] {
        assert!(text.contains(expected), "missing {expected:?} in\n{text}");
    }
    assert!(text.ends_with(
        "7,8;                      $ parameters\n\n$ DNS V5 Extended Configuration Demo EDS File\n"
    ));
}

#[test]
fn comments_before_entries_and_at_line_ends_move_with_their_entry() {
    // [Device] comes first in the file, the writer puts [File] first; ProdCode moves up.
    let text = b"$ tool\n\n$ about Device\n[Device] $ identity\n$ product\nProdCode = 7; $ seven\n\
        VendCode = 1;\n[File]\nDescText = \"x\"; $ text\n$ the end\n";
    let out = String::from_utf8(format(text)).unwrap();
    let expected = "$ tool

[File]
        DescText = \"x\";                   $ text

$ about Device
[Device]  $ identity
        VendCode = 1;
        $ product
        ProdCode = 7;                     $ seven

$ the end
";
    assert_eq!(out, expected);
    assert_eq!(format(out.as_bytes()), out.as_bytes());
}

/// Every byte 0x80..=0xFF, as Latin-1 text.
fn high_bytes() -> Vec<u8> {
    (0x80..=0xFF).collect()
}

#[test]
fn latin1_bytes_in_strings_comments_and_text_survive_format() {
    let high = high_bytes();
    let mut file = b"$ header ".to_vec();
    file.extend(&high);
    file.extend(b"\n\n[Device]\n        VendName = \"");
    file.extend(&high);
    file.extend(b"\"; $ ");
    file.extend(&high);
    file.extend(b"\n[Device Classification]\n        Class1 = Device\xa0Net\x85x;\n");
    assert!(std::str::from_utf8(&file).is_err(), "the input must be Latin-1");

    let out = format(&file);
    let find = |needle: &[u8]| out.windows(needle.len()).any(|w| w == needle);
    let mut in_string = b"VendName = \"".to_vec();
    in_string.extend(&high);
    in_string.push(b'"');
    assert!(find(&in_string), "string bytes changed:\n{}", String::from_utf8_lossy(&out));
    let mut in_comment = b"$ ".to_vec();
    in_comment.extend(&high);
    in_comment.push(b'\n');
    assert!(find(&in_comment), "comment bytes changed:\n{}", String::from_utf8_lossy(&out));
    let mut header = b"$ header ".to_vec();
    header.extend(&high);
    assert!(out.starts_with(&header), "header bytes changed:\n{}", String::from_utf8_lossy(&out));
    assert!(
        find(b"Class1 = Device\xa0Net\x85x;"),
        "unquoted bytes changed:\n{}",
        String::from_utf8_lossy(&out)
    );
    assert!(!find(b"\\x"), "escaped bytes:\n{}", String::from_utf8_lossy(&out));
    assert_eq!(format(&out), out);
}

#[test]
fn latin1_corpus_file_keeps_its_bytes() {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/corpus/latin1.eds");
    let bytes = std::fs::read(path).unwrap();
    let out = format(&bytes);
    let high = |b: &[u8]| b.iter().copied().filter(|&b| b >= 0x80).collect::<Vec<u8>>();
    assert!(!high(&bytes).is_empty());
    assert_eq!(high(&out), high(&bytes), "{}", String::from_utf8_lossy(&out));
}

#[test]
fn utf8_files_stay_utf8() {
    let file = "[Device]\n        VendName = \"M\u{fc}ller \u{b0}C \u{92}\"; $ \u{20ac}\n";
    let out = String::from_utf8(format(file.as_bytes())).unwrap();
    assert!(out.contains("VendName = \"M\u{fc}ller \u{b0}C \u{92}\";"), "{out}");
    assert!(out.contains("$ \u{20ac}\n"), "{out}");
}
