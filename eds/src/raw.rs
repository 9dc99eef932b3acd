//! The raw layer: tokens to sections, entries and fields, keeping every spelling and position.
//!
//! Grammar (case is kept here and ignored by the layers above):
//!
//! ```text
//! file    = { section }
//! section = "[" name "]" { entry }
//! entry   = keyword "=" field { "," field } ";"        (may span any number of lines)
//! field   = empty | word { word } | string { string } | "{" field { "," field } "}"
//! ```
//!
//! Adjacent strings are concatenated (`"abc" "def"` is `abcdef`), adjacent words are joined by
//! one space, empty fields are kept (`,,` is an empty field).
//!
//! The parser recovers from errors so one pass reports them all: an entry missing its `;` ends
//! where the next `keyword =` starts, and the error points just after the entry's last value
//! (where the `;` belongs); an unterminated string is reported once, at its opening quote, and
//! nothing else is reported until the next entry or section starts; anything else unexpected skips to the next `;` or
//! section.
//!
//! `$` comments are not part of [`RawEds`]; the parser keeps them with the entries' ends
//! (`Parsed`), and [`RawEds::parse_with_comments`] (in the comments module, which builds on this
//! one) attaches them to sections and entries.
//! Input size, section, entry, field and nesting counts are capped ([`crate::limits`]); hitting a
//! cap stops the parse with a [`SyntaxError::TooMany`] or [`SyntaxError::TooDeep`] error.

use crate::diag::Span;
use crate::error::{ParseError, SyntaxError};
use crate::lexer::{Comment, Lexer, Tok, Token};
use crate::limits::{MAX_ENTRIES, MAX_FIELDS, MAX_NESTING, MAX_SECTIONS};
use serde::Serialize;

/// A whole EDS file as sections of entries, before any interpretation.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct RawEds {
    /// Sections in file order (a repeated section appears twice).
    pub sections: Vec<RawSection>,
}

/// One `[Section]` and its entries.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct RawSection {
    /// The name as written between the brackets, trimmed.
    pub name: String,
    /// Position of the `[`.
    pub span: Span,
    /// Entries in file order.
    pub entries: Vec<RawEntry>,
}

/// One `Keyword = field, field, ...;` entry.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct RawEntry {
    /// The keyword as written.
    pub keyword: String,
    /// Position of the keyword.
    pub span: Span,
    /// The fields; an entry always has at least one (possibly empty) field.
    pub fields: Vec<Field>,
}

/// One comma-separated field of an entry.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Field {
    /// The value.
    pub value: FieldValue,
    /// Position of the field's first token (of the following `,`/`;` for an empty field).
    pub span: Span,
}

/// The value of a [`Field`].
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
#[serde(tag = "kind", content = "value", rename_all = "lowercase")]
pub enum FieldValue {
    /// Nothing between the separators.
    Empty,
    /// Unquoted text (numbers, dates, identifiers), words joined by one space.
    Text(String),
    /// One or more adjacent quoted strings, concatenated, escapes resolved.
    Str(String),
    /// A `{ ... }` group of fields.
    List(Vec<Field>),
}

impl FieldValue {
    /// The text of a [`FieldValue::Text`] or [`FieldValue::Str`].
    pub fn as_text(&self) -> Option<&str> {
        match self {
            FieldValue::Text(text) | FieldValue::Str(text) => Some(text),
            _ => None,
        }
    }

    /// `true` for [`FieldValue::Empty`].
    pub fn is_empty(&self) -> bool {
        matches!(self, FieldValue::Empty)
    }
}

/// One pass of the parser over a text, before the comments are attached.
pub(crate) struct Parsed {
    /// The sections found.
    pub(crate) raw: RawEds,
    /// Where each entry ends, in file order.
    pub(crate) entry_ends: Vec<Span>,
    /// The `$` comments, in file order.
    pub(crate) comments: Vec<Comment>,
    /// Every syntax error, by position.
    pub(crate) errors: Vec<ParseError>,
}

impl RawEds {
    /// Parses decoded text, recovering from errors: the sections found, and every syntax error
    /// (empty when the text is well-formed).
    pub fn parse_lenient(text: &str) -> (RawEds, Vec<ParseError>) {
        let parsed = RawEds::parse_all(text);
        (parsed.raw, parsed.errors)
    }

    /// Parses decoded text, keeping what the comments layer needs: the sections, where each entry
    /// ends, the `$` comments and every syntax error.
    pub(crate) fn parse_all(text: &str) -> Parsed {
        let mut parser = Parser::new(text);
        let raw = parser.file();
        let mut errors = parser.errors;
        errors.extend(parser.lexer.take_errors());
        errors.sort_by_key(|e| e.span);
        let comments = parser.lexer.take_comments();
        Parsed { raw, entry_ends: parser.entry_ends, comments, errors }
    }

    /// Parses decoded text.
    ///
    /// # Errors
    ///
    /// The first syntax error in the text.
    pub fn parse(text: &str) -> Result<RawEds, ParseError> {
        let (raw, errors) = RawEds::parse_lenient(text);
        match errors.into_iter().next() {
            Some(error) => Err(error),
            None => Ok(raw),
        }
    }

    /// The sections whose name matches `name` ignoring case and repeated whitespace.
    pub fn sections_named<'a>(&'a self, name: &str) -> impl Iterator<Item = &'a RawSection> + 'a {
        let wanted = normalize_name(name);
        self.sections.iter().filter(move |s| normalize_name(&s.name) == wanted)
    }

    /// The first entry `keyword` in the first section `section` that has it (names ignore case).
    pub fn entry(&self, section: &str, keyword: &str) -> Option<&RawEntry> {
        self.sections_named(section).find_map(|s| s.entry(keyword))
    }
}

impl RawSection {
    /// The first entry whose keyword matches `keyword` ignoring case.
    pub fn entry(&self, keyword: &str) -> Option<&RawEntry> {
        self.entries.iter().find(|e| e.keyword.eq_ignore_ascii_case(keyword))
    }
}

impl RawEntry {
    /// The vendor ID and name of a vendor-specific keyword (`283_MyKeyword` is `(283, "MyKeyword")`).
    pub fn vendor_prefix(&self) -> Option<(u32, &str)> {
        vendor_prefix(&self.keyword)
    }
}

/// Splits a vendor-specific keyword or section name `VENDOR_Name` into `(VENDOR, "Name")`.
pub fn vendor_prefix(name: &str) -> Option<(u32, &str)> {
    let (vendor, rest) = name.split_once('_')?;
    if vendor.is_empty() || !vendor.bytes().all(|b| b.is_ascii_digit()) || rest.is_empty() {
        return None;
    }
    Some((vendor.parse().ok()?, rest))
}

/// The form names are compared in: lower case, whitespace runs as one space.
pub fn normalize_name(name: &str) -> String {
    name.split_whitespace().collect::<Vec<_>>().join(" ").to_ascii_lowercase()
}

fn is_keyword(word: &str) -> bool {
    !word.is_empty() && word.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
}

/// What a field has accumulated so far.
enum Acc {
    Nothing,
    Words(Vec<(String, Span)>),
    Strings(String),
    List(Vec<Field>),
}

struct FieldBuilder {
    acc: Acc,
    span: Option<Span>,
}

impl FieldBuilder {
    fn new() -> FieldBuilder {
        FieldBuilder { acc: Acc::Nothing, span: None }
    }

    fn finish(self, at: Span) -> Field {
        let value = match self.acc {
            Acc::Nothing => FieldValue::Empty,
            Acc::Words(words) => {
                FieldValue::Text(words.into_iter().map(|(w, _)| w).collect::<Vec<_>>().join(" "))
            }
            Acc::Strings(text) => FieldValue::Str(text),
            Acc::List(fields) => FieldValue::List(fields),
        };
        Field { value, span: self.span.unwrap_or(at) }
    }
}

/// A keyword and its position.
type Keyword = (String, Span);

/// How a list of fields ended.
enum End {
    /// `;` (or `}` in a group).
    Closed,
    /// The next entry starts: the keyword and its span; the `=` is still to be read.
    NextEntry(String, Span),
    /// A section header or the end of input (not consumed).
    Cut,
}

struct Parser<'a> {
    lexer: Lexer<'a>,
    peeked: Option<Token>,
    errors: Vec<ParseError>,
    /// Where the last consumed token ends, and the one before it.
    last_end: Span,
    prev_end: Span,
    /// The entry being read contains an unterminated string (already reported by the lexer):
    /// the errors that follow from it are not reported again.
    broken: bool,
    /// Where each entry kept in a section ends (just after its `;` or last value), in file order.
    entry_ends: Vec<Span>,
    entries: usize,
    fields: usize,
    /// A limit was hit: the parse stops.
    stopped: bool,
}

impl<'a> Parser<'a> {
    fn new(text: &'a str) -> Parser<'a> {
        Parser {
            lexer: Lexer::new(text),
            peeked: None,
            errors: Vec::new(),
            last_end: Span::START,
            prev_end: Span::START,
            broken: false,
            entry_ends: Vec::new(),
            entries: 0,
            fields: 0,
            stopped: false,
        }
    }

    fn peek(&mut self) -> &Token {
        if self.stopped {
            self.peeked = Some(Token { tok: Tok::Eof, span: Span::START, end: Span::START });
        }
        let lexer = &mut self.lexer;
        self.peeked.get_or_insert_with(|| lexer.next_token())
    }

    fn next(&mut self) -> Token {
        self.peek();
        let token =
            self.peeked.take().unwrap_or(Token { tok: Tok::Eof, span: Span::START, end: Span::START });
        if token.tok != Tok::Eof {
            self.prev_end = std::mem::replace(&mut self.last_end, token.end);
        }
        token
    }

    fn error(&mut self, span: Span, kind: SyntaxError) {
        // After an unterminated string, the rest of its entry is read as it comes: what looks
        // wrong there follows from the one error already reported.
        if self.broken && !matches!(kind, SyntaxError::TooMany { .. } | SyntaxError::TooDeep(_)) {
            return;
        }
        self.errors.push(ParseError::new(span, kind));
    }

    fn stop(&mut self, span: Span, kind: SyntaxError) {
        self.error(span, kind);
        self.stopped = true;
    }

    /// Skips to just after the next `;`, or to (not past) the next section header.
    fn recover(&mut self) {
        loop {
            match self.peek().tok {
                Tok::Eof | Tok::Section(_) => return,
                Tok::Semicolon => {
                    self.next();
                    return;
                }
                _ => {
                    self.next();
                }
            }
        }
    }

    fn file(&mut self) -> RawEds {
        let mut raw = RawEds::default();
        let mut pending: Option<(String, Span)> = None;
        loop {
            let (keyword, span) = match pending.take() {
                Some(next) => next,
                None => {
                    let token = self.next();
                    match token.tok {
                        Tok::Eof => break,
                        Tok::Section(name) => {
                            if raw.sections.len() >= MAX_SECTIONS {
                                self.stop(
                                    token.span,
                                    SyntaxError::TooMany { what: "sections", limit: MAX_SECTIONS },
                                );
                                break;
                            }
                            self.broken = false;
                            if name.is_empty() {
                                self.error(token.span, SyntaxError::EmptySectionName);
                            }
                            raw.sections.push(RawSection { name, span: token.span, entries: Vec::new() });
                            continue;
                        }
                        Tok::Word(word) => (word, token.span),
                        // Already reported by the lexer.
                        Tok::UnterminatedStr(_) => continue,
                        other => {
                            self.error(token.span, SyntaxError::ExpectedKeyword(other.describe()));
                            if other != Tok::Semicolon {
                                self.recover();
                            }
                            continue;
                        }
                    }
                }
            };
            let (entry, next) = self.entry(keyword, span);
            pending = next;
            let Some((entry, end)) = entry else { continue };
            self.entries += 1;
            if self.entries > MAX_ENTRIES {
                self.stop(entry.span, SyntaxError::TooMany { what: "entries", limit: MAX_ENTRIES });
                break;
            }
            match raw.sections.last_mut() {
                Some(section) => {
                    section.entries.push(entry);
                    self.entry_ends.push(end);
                }
                None => self.error(entry.span, SyntaxError::EntryOutsideSection(entry.keyword)),
            }
        }
        raw
    }

    /// An entry after its keyword, with where it ends; also returns the keyword of a following
    /// entry when this one was cut short by it (missing `;`).
    fn entry(&mut self, keyword: String, span: Span) -> (Option<(RawEntry, Span)>, Option<Keyword>) {
        self.broken = false;
        if !is_keyword(&keyword) {
            self.error(span, SyntaxError::InvalidKeyword(keyword.clone()));
        }
        let token = self.peek().clone();
        if token.tok != Tok::Equals {
            self.error(
                token.span,
                SyntaxError::ExpectedEquals { keyword: keyword.clone(), found: token.tok.describe() },
            );
            if matches!(token.tok, Tok::Section(_)) {
                return (None, None);
            }
            self.recover();
            return (None, None);
        }
        self.next();
        let (fields, end) = self.fields(&keyword, 0);
        // Where the entry's last value ends: the `;` belongs there when it is missing.
        let closed = matches!(end, End::Closed);
        let (value_end, next) = match end {
            End::Closed => (self.last_end, None),
            // The next entry's keyword has been read already.
            End::NextEntry(next, next_span) => (self.prev_end, Some((next, next_span))),
            End::Cut => (self.last_end, None),
        };
        if !closed && !self.stopped {
            self.error(value_end, SyntaxError::MissingSemicolon(keyword.clone()));
        }
        (Some((RawEntry { keyword, span, fields }, value_end)), next)
    }

    fn push_field(&mut self, fields: &mut Vec<Field>, builder: FieldBuilder, at: Span) {
        self.fields += 1;
        if self.fields > MAX_FIELDS {
            self.stop(at, SyntaxError::TooMany { what: "fields", limit: MAX_FIELDS });
            return;
        }
        fields.push(builder.finish(at));
    }

    /// Fields up to `;` (depth 0) or `}` (inside a group).
    fn fields(&mut self, keyword: &str, depth: usize) -> (Vec<Field>, End) {
        let mut fields = Vec::new();
        let mut current = FieldBuilder::new();
        loop {
            let token = self.peek().clone();
            if matches!(token.tok, Tok::UnterminatedStr(_)) {
                self.broken = true;
            }
            match token.tok {
                Tok::Comma => {
                    self.next();
                    self.push_field(
                        &mut fields,
                        std::mem::replace(&mut current, FieldBuilder::new()),
                        token.span,
                    );
                }
                Tok::Semicolon if depth == 0 => {
                    self.next();
                    self.push_field(&mut fields, current, token.span);
                    return (fields, End::Closed);
                }
                Tok::Semicolon => {
                    self.error(token.span, SyntaxError::UnclosedBrace(keyword.to_string()));
                    self.push_field(&mut fields, current, token.span);
                    return (fields, End::Closed);
                }
                Tok::RBrace if depth > 0 => {
                    self.next();
                    self.push_field(&mut fields, current, token.span);
                    return (fields, End::Closed);
                }
                Tok::RBrace => {
                    self.next();
                    self.error(token.span, SyntaxError::UnmatchedBrace(keyword.to_string()));
                }
                Tok::Section(_) | Tok::Eof => {
                    if depth > 0 && !self.stopped {
                        self.error(token.span, SyntaxError::UnclosedBrace(keyword.to_string()));
                    }
                    self.push_field(&mut fields, current, token.span);
                    return (fields, End::Cut);
                }
                Tok::Equals => {
                    // `A = 1 B = 2;`: the last word before '=' starts the next entry (whose
                    // parse reads the '=').
                    if let Acc::Words(words) = &mut current.acc {
                        if let Some((next, next_span)) = words.pop() {
                            if words.is_empty() {
                                current = FieldBuilder::new();
                            }
                            self.push_field(&mut fields, current, next_span);
                            return (fields, End::NextEntry(next, next_span));
                        }
                    }
                    self.next();
                    self.error(
                        token.span,
                        SyntaxError::UnexpectedToken {
                            keyword: keyword.to_string(),
                            found: "'='".to_string(),
                        },
                    );
                }
                Tok::Word(word) => {
                    self.next();
                    current.span.get_or_insert(token.span);
                    match &mut current.acc {
                        Acc::Nothing => current.acc = Acc::Words(vec![(word, token.span)]),
                        Acc::Words(words) => words.push((word, token.span)),
                        Acc::Strings(_) | Acc::List(_) => {
                            // `A = "x" B = 2;`: a word then '=' after a string starts the next entry.
                            if self.peek().tok == Tok::Equals {
                                self.push_field(&mut fields, current, token.span);
                                return (fields, End::NextEntry(word, token.span));
                            }
                            self.error(token.span, SyntaxError::MixedField(keyword.to_string()));
                        }
                    }
                }
                Tok::Str(text) | Tok::UnterminatedStr(text) => {
                    self.next();
                    current.span.get_or_insert(token.span);
                    match &mut current.acc {
                        Acc::Nothing => current.acc = Acc::Strings(text),
                        Acc::Strings(all) => all.push_str(&text),
                        Acc::Words(_) | Acc::List(_) => {
                            self.error(token.span, SyntaxError::MixedField(keyword.to_string()));
                        }
                    }
                }
                Tok::LBrace => {
                    self.next();
                    if depth + 1 > MAX_NESTING {
                        self.stop(token.span, SyntaxError::TooDeep(MAX_NESTING));
                        return (fields, End::Cut);
                    }
                    let (inner, end) = self.fields(keyword, depth + 1);
                    if matches!(current.acc, Acc::Nothing) {
                        current.span = Some(token.span);
                        current.acc = Acc::List(inner);
                    } else {
                        self.error(
                            token.span,
                            SyntaxError::UnexpectedToken {
                                keyword: keyword.to_string(),
                                found: "'{'".to_string(),
                            },
                        );
                    }
                    match end {
                        End::Closed => {}
                        other => {
                            self.push_field(&mut fields, current, token.span);
                            return (fields, other);
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    fn text(s: &str) -> FieldValue {
        FieldValue::Text(s.to_string())
    }

    fn string(s: &str) -> FieldValue {
        FieldValue::Str(s.to_string())
    }

    fn values(entry: &RawEntry) -> Vec<FieldValue> {
        entry.fields.iter().map(|f| f.value.clone()).collect()
    }

    fn only_entry(src: &str) -> RawEntry {
        let raw = RawEds::parse(src).unwrap();
        assert_eq!(raw.sections.len(), 1);
        assert_eq!(raw.sections[0].entries.len(), 1);
        raw.sections[0].entries[0].clone()
    }

    #[rstest]
    #[case::single("[S]\nA = 1;", vec![text("1")])]
    #[case::spanning_lines("[S]\nA =\n  1,\n  2;", vec![text("1"), text("2")])]
    #[case::empty_fields("[S]\nA = ,,;", vec![FieldValue::Empty, FieldValue::Empty, FieldValue::Empty])]
    #[case::empty_value("[S]\nA = ;", vec![FieldValue::Empty])]
    #[case::adjacent_strings("[S]\nA = \"abc\"\n  \"def\";", vec![string("abcdef")])]
    #[case::strings_around_comment("[S]\nA = \"abc\" $ note\n \"def\";", vec![string("abcdef")])]
    #[case::words_joined("[S]\nA = Hold   Last;", vec![text("Hold Last")])]
    #[case::comment_between_fields("[S]\nA = 1, $ one\n 2; $ done", vec![text("1"), text("2")])]
    #[case::group("[S]\nA = 1, {2, \"x\"}, 3;", vec![
        text("1"),
        FieldValue::List(vec![
            Field { value: text("2"), span: Span::new(2, 9) },
            Field { value: string("x"), span: Span::new(2, 12) },
        ]),
        text("3"),
    ])]
    fn parses_fields(#[case] src: &str, #[case] expected: Vec<FieldValue>) {
        assert_eq!(values(&only_entry(src)), expected);
    }

    #[test]
    fn keeps_positions_of_sections_entries_and_fields() {
        let raw = RawEds::parse("$ c\n[File]\n  DescText = \"x\",\n   7;\n").unwrap();
        let section = &raw.sections[0];
        assert_eq!(section.span, Span::new(2, 1));
        let entry = &section.entries[0];
        assert_eq!(entry.span, Span::new(3, 3));
        assert_eq!(entry.fields[0].span, Span::new(3, 14));
        assert_eq!(entry.fields[1].span, Span::new(4, 4));
    }

    #[test]
    fn names_compare_case_insensitively() {
        let raw = RawEds::parse("[io_info]\n default = 1;\n[DEVICE   classification]\n Class1 = DeviceNet;")
            .unwrap();
        assert!(raw.entry("IO_Info", "Default").is_some());
        assert!(raw.entry("Device Classification", "CLASS1").is_some());
    }

    #[rstest]
    #[case::vendor_keyword("1_VendorKeyword", Some((1, "VendorKeyword")))]
    #[case::vendor_283("283_Fw", Some((283, "Fw")))]
    #[case::plain("VendCode", None)]
    #[case::no_name("283_", None)]
    #[case::letters_first("A1_x", None)]
    fn splits_vendor_prefix(#[case] name: &str, #[case] expected: Option<(u32, &str)>) {
        assert_eq!(vendor_prefix(name), expected);
    }

    #[rstest]
    #[case::missing_semicolon("[S]\nA = 1\nB = 2;", SyntaxError::MissingSemicolon("A".into()), Span::new(2, 6))]
    #[case::missing_semicolon_multi_line("[S]\nA =\n 1,\n 2\nB = 2;", SyntaxError::MissingSemicolon("A".into()), Span::new(4, 3))]
    #[case::missing_semicolon_before_section("[S]\nA = 1 $ c\n\n[T]", SyntaxError::MissingSemicolon("A".into()), Span::new(2, 6))]
    #[case::missing_semicolon_at_eof("[S]\nA = 1", SyntaxError::MissingSemicolon("A".into()), Span::new(2, 6))]
    #[case::missing_equals("[S]\nA 1;", SyntaxError::ExpectedEquals { keyword: "A".into(), found: "`1`".into() }, Span::new(2, 3))]
    #[case::outside_section("A = 1;", SyntaxError::EntryOutsideSection("A".into()), Span::new(1, 1))]
    #[case::mixed_field("[S]\nA = \"x\" y;", SyntaxError::MixedField("A".into()), Span::new(2, 9))]
    #[case::stray_semicolon("[S]\n;", SyntaxError::ExpectedKeyword("';'".into()), Span::new(2, 1))]
    #[case::empty_section_name("[ ]", SyntaxError::EmptySectionName, Span::new(1, 1))]
    #[case::invalid_keyword("[S]\nA-B = 1;", SyntaxError::InvalidKeyword("A-B".into()), Span::new(2, 1))]
    #[case::unclosed_brace("[S]\nA = {1;", SyntaxError::UnclosedBrace("A".into()), Span::new(2, 7))]
    #[case::unmatched_brace("[S]\nA = 1};", SyntaxError::UnmatchedBrace("A".into()), Span::new(2, 6))]
    fn reports_syntax_errors(#[case] src: &str, #[case] kind: SyntaxError, #[case] span: Span) {
        let (_, errors) = RawEds::parse_lenient(src);
        assert_eq!(errors.first(), Some(&ParseError::new(span, kind)), "all: {errors:?}");
    }

    #[test]
    fn recovers_after_missing_semicolon_after_string() {
        let (raw, errors) = RawEds::parse_lenient("[File]\nDescText = \"x\"\nRevision = 1.0;");
        assert_eq!(
            errors,
            vec![ParseError::new(Span::new(2, 15), SyntaxError::MissingSemicolon("DescText".into()))]
        );
        assert_eq!(raw.sections[0].entries.len(), 2);
    }

    #[test]
    fn recovers_after_missing_semicolon() {
        let (raw, errors) =
            RawEds::parse_lenient("[Device]\nVendCode = 283\nVendName = \"x\";\nProdCode = 3;");
        assert_eq!(errors.len(), 1);
        let keywords: Vec<_> = raw.sections[0].entries.iter().map(|e| e.keyword.as_str()).collect();
        assert_eq!(keywords, ["VendCode", "VendName", "ProdCode"]);
        assert_eq!(values(&raw.sections[0].entries[0]), vec![text("283")]);
    }

    #[test]
    fn nesting_is_capped() {
        let src = format!("[S]\nA = {};", "{".repeat(MAX_NESTING + 5));
        let (_, errors) = RawEds::parse_lenient(&src);
        assert!(errors.iter().any(|e| e.kind == SyntaxError::TooDeep(MAX_NESTING)));
    }
}
