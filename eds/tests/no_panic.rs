//! Property tests: no input makes any layer panic, and whatever parses cleanly writes back to
//! text that parses to the same writer output.

use eds::{check, parse, Eds, RawEds, Writer};
use proptest::prelude::*;

/// Every layer on arbitrary input.
fn all_layers(bytes: &[u8]) {
    let _ = parse(bytes);
    let _ = check(bytes);
    let (text, _) = eds::text::decode(bytes).unwrap();
    let (raw, _) = RawEds::parse_lenient(&text);
    let (eds, _) = Eds::from_raw(&raw);
    let _ = Writer::new().write(&eds);
    let _ = eds::Summary::of(&eds).to_string();
    let _ = serde_json::to_string(&eds::Summary::of(&eds)).unwrap();
}

/// Text made of EDS tokens, so the parser gets past the first character.
fn eds_like() -> impl Strategy<Value = String> {
    let token = prop_oneof![
        Just("[File]".to_string()),
        Just("[Params]".to_string()),
        Just("[EnumPar]".to_string()),
        Just("[Groups]".to_string()),
        Just("[IO_Info]".to_string()),
        Just("[Device]".to_string()),
        Just("[".to_string()),
        Just("]".to_string()),
        Just("=".to_string()),
        Just(",".to_string()),
        Just(";".to_string()),
        Just("{".to_string()),
        Just("}".to_string()),
        Just("\"".to_string()),
        Just("\\".to_string()),
        Just("$".to_string()),
        Just("\n".to_string()),
        Just("\r".to_string()),
        Just(" ".to_string()),
        Just("Param1".to_string()),
        Just("Enum1".to_string()),
        Just("Group1".to_string()),
        Just("PollInfo".to_string()),
        Just("Input1".to_string()),
        Just("VendCode".to_string()),
        Just("0xC6".to_string()),
        Just("-1".to_string()),
        Just("1.5".to_string()),
        "[A-Za-z0-9_]{1,6}",
        "\"[ -~]{0,6}\"",
        any::<u8>().prop_map(|b| char::from(b).to_string()),
    ];
    prop::collection::vec(token, 0..300).prop_map(|tokens| tokens.concat())
}

/// A quoted EDS string holding arbitrary characters (escaping only `\\` and `"`, so line
/// breaks, `$`, `;` and non-ASCII appear raw inside the quotes).
fn quoted() -> impl Strategy<Value = String> {
    prop::collection::vec(any::<char>(), 0..12).prop_map(|chars| {
        let mut out = String::from("\"");
        for c in chars {
            match c {
                '\\' => out.push_str("\\\\"),
                '"' => out.push_str("\\\""),
                // A line of a string never starts like an entry or a section header: that reads
                // as a string missing its closing quote (see the lexer rules).
                '\n' | '\r' => {
                    out.push(c);
                    out.push('.');
                }
                c => out.push(c),
            }
        }
        out.push('"');
        out
    })
}

fn field() -> BoxedStrategy<String> {
    let leaf = prop_oneof![
        Just(String::new()),
        "[A-Za-z0-9_.:+-]{1,8}",
        "[A-Za-z]{1,5} [A-Za-z]{1,5}",
        "-?[0-9]{1,4}",
        "0[xX][0-9A-Fa-f]{1,4}",
        quoted(),
        (quoted(), quoted()).prop_map(|(a, b)| format!("{a}\n   {b}")),
    ];
    leaf.prop_recursive(2, 8, 3, |inner| {
        prop::collection::vec(inner, 1..3).prop_map(|fields| format!("{{{}}}", fields.join(", ")))
    })
    .boxed()
}

/// Well-formed EDS text: sections with entries of arbitrary fields.
fn well_formed() -> impl Strategy<Value = String> {
    let keyword = prop_oneof![
        Just("Param1".to_string()),
        Just("Param2".to_string()),
        Just("Enum1".to_string()),
        Just("Group1".to_string()),
        Just("VendCode".to_string()),
        Just("ProdName".to_string()),
        Just("DescText".to_string()),
        Just("CreateDate".to_string()),
        Just("Input1".to_string()),
        Just("PollInfo".to_string()),
        Just("Default".to_string()),
        Just("Class1".to_string()),
        Just("MaxInst".to_string()),
        Just("283_Vendor".to_string()),
        "[A-Za-z][A-Za-z0-9_]{0,8}",
    ];
    let entry = (keyword, prop::collection::vec(field(), 1..24))
        .prop_map(|(k, fields)| format!("  {k} = {}; $ comment\n", fields.join(",\n    ")));
    let name = prop_oneof![
        Just("File".to_string()),
        Just("Device".to_string()),
        Just("Device Classification".to_string()),
        Just("IO_Info".to_string()),
        Just("ParamClass".to_string()),
        Just("Params".to_string()),
        Just("EnumPar".to_string()),
        Just("Groups".to_string()),
        "[A-Za-z][A-Za-z0-9_ ]{0,10}[A-Za-z0-9_]",
    ];
    let section = (name, prop::collection::vec(entry, 0..6))
        .prop_map(|(name, entries)| format!("[{name}]\n{}", entries.concat()));
    prop::collection::vec(section, 0..6).prop_map(|sections| sections.concat())
}

/// Every comment of `text`, as the parser finds them.
fn comment_texts(text: &str) -> Vec<String> {
    let comments = eds::RawEds::parse_with_comments(text).unwrap().1;
    let mut all = comments.header.clone();
    for attached in comments.sections.values().chain(comments.entries.values()) {
        all.extend(attached.before.iter().cloned());
        all.extend(attached.end_of_line.iter().cloned());
        all.extend(attached.fields.values().flatten().cloned());
    }
    all.extend(comments.trailer);
    all.retain(|c| !c.is_empty());
    all
}

/// Well-formed text with `$` comments added: lines above sections and entries, blank lines
/// between them, comments at line ends (inside a string spanning lines, such a comment is text).
fn well_formed_with_comments() -> impl Strategy<Value = String> {
    let comment = "[ !#-\\[\\]-~\u{80}-\u{ff}]{0,12}";
    (well_formed(), prop::collection::vec((0u8..6, comment), 0..96)).prop_map(|(text, inserts)| {
        let mut out = String::new();
        let mut inserts = inserts.into_iter();
        for line in text.lines() {
            match inserts.next() {
                Some((0, c)) => out.push_str(&format!("$ {c}\n{line}\n")),
                Some((1, _)) => out.push_str(&format!("\n{line}\n")),
                Some((2, c)) => out.push_str(&format!("{line} ${c}\n")),
                _ => out.push_str(&format!("{line}\n")),
            }
        }
        if let Some((_, c)) = inserts.next() {
            out.push_str(&format!("\n$ {c}\n"));
        }
        out
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    #[test]
    fn format_keeps_comments_and_is_a_fixed_point(text in well_formed_with_comments()) {
        let once = eds::format(text.as_bytes());
        prop_assert!(once.is_ok(), "{:?}\n{}", once, text);
        let once = once.unwrap();
        let twice = eds::format(&once).unwrap();
        prop_assert_eq!(String::from_utf8_lossy(&twice), String::from_utf8_lossy(&once), "input:\n{}", text);
        // The same model: written without comments, both give the same text.
        let model = |bytes: &[u8]| Writer::new().write(&eds::parse(bytes).unwrap());
        prop_assert_eq!(model(&once), model(text.as_bytes()));
        // Every comment of the input is a comment of the output.
        let out = String::from_utf8(once).unwrap();
        let kept = comment_texts(&out).join("\n");
        for comment in comment_texts(&text) {
            prop_assert!(kept.contains(&comment), "lost comment {:?}\n{}", comment, out);
        }
    }

    #[test]
    fn arbitrary_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..4096)) {
        all_layers(&bytes);
    }

    #[test]
    fn eds_like_text_never_panics(text in eds_like()) {
        all_layers(text.as_bytes());
    }

    #[test]
    fn well_formed_text_parses_and_writes_back_stably(text in well_formed()) {
        let eds = eds::parse_str(&text);
        prop_assert!(eds.is_ok(), "{:?}\n{}", eds, text);
        let first = Writer::new().write(&eds.unwrap());
        let again = eds::parse_str(&first);
        prop_assert!(again.is_ok(), "written text does not parse: {:?}\n{}", again, first);
        let again = again.unwrap();
        let second = Writer::new().write(&again);
        prop_assert_eq!(&second, &first);
        prop_assert_eq!(eds::parse_str(&second).unwrap(), again);
        all_layers(text.as_bytes());
    }

    #[test]
    fn clean_parses_write_back_stably(text in eds_like()) {
        if let Ok(eds) = eds::parse_str(&text) {
            let first = Writer::new().write(&eds);
            let again = eds::parse_str(&first);
            prop_assert!(again.is_ok(), "written text does not parse: {:?}\n{}", again, first);
            let again = again.unwrap();
            prop_assert_eq!(Writer::new().write(&again), first);
        }
    }
}

#[test]
fn deep_nesting_and_long_inputs_are_bounded() {
    all_layers(format!("[S]\nA = {};", "{".repeat(100_000)).as_bytes());
    all_layers(format!("[S]\nA = {};", ",".repeat(3_000_000)).as_bytes());
    all_layers("[S]\n".repeat(20_000).as_bytes());
    // Many dangling references and duplicate members stay linear.
    let members: Vec<String> = (1..200_000).map(|n| (n % 100_000).to_string()).collect();
    all_layers(
        format!(
            "[Groups]\nGroup1 = \"g\", 1, {};\n[Params]\nEnum1 = {};",
            members.join(","),
            members.join(",")
        )
        .as_bytes(),
    );
    let report = check(&vec![b'x'; eds::limits::MAX_INPUT_BYTES + 1]);
    assert!(report.has_errors());
}
