//! The lexer: decoded text to tokens, with line and column.
//!
//! EDS lexical rules handled here:
//!
//! - `$` starts a comment that runs to the end of the line, except inside a quoted string;
//! - `"..."` strings may span lines (a line break inside is kept as `\n`) and understand the
//!   escapes `\\`, `\"`, `\n`, `\t`, `\r` and `\xHH`; an unknown escape is kept literally (so a
//!   Windows path such as `"C:\eds\x.ico"` survives); adjacent strings are joined by the parser;
//! - a string is taken as unterminated at its first line break when the text after that break
//!   cannot be the rest of a string: a later line is a section header or starts an entry
//!   (`Keyword =`) before the next `"`, or that `"` is followed on its line by something other than `,`, `;`,
//!   `}`, a comment, the line end or (after a space) another string. The lexer then reports the
//!   string once, at its opening quote, and carries on at the next line, so a missing `"` does
//!   not swap strings and text for the rest of the file;
//! - whitespace is ASCII (space, tab, line breaks, vertical tab, form feed): bytes 0x80–0xFF of a
//!   Latin-1 file, such as a no-break space, are text like any other;
//! - `[name]` is a section header; `=`, `,`, `;`, `{`, `}` are punctuation;
//! - everything else up to whitespace or punctuation is a word (keywords, numbers such as `0x00C6`,
//!   dates, unquoted identifiers such as `DeviceNet`);
//! - line breaks are `\n`, `\r\n` or a lone `\r`; DOS end-of-file (0x1A) and NUL count as
//!   whitespace.
//!
//! Comments are not tokens: the lexer keeps each one, with its position, for [`crate::comments`].
//!
//! The lexer never fails: problems (an unterminated string or section header) are recorded as
//! [`ParseError`]s and a best-effort token is still produced.

use crate::diag::Span;
use crate::error::{ParseError, SyntaxError};
use std::iter::Peekable;
use std::str::Chars;

/// A token kind with its text.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum Tok {
    /// `[name]`, name trimmed.
    Section(String),
    /// Unquoted text.
    Word(String),
    /// One quoted string literal, escapes resolved.
    Str(String),
    /// A string with no closing quote (already reported), cut at its first line break or at the
    /// end of input.
    UnterminatedStr(String),
    /// `=`
    Equals,
    /// `,`
    Comma,
    /// `;`
    Semicolon,
    /// `{`
    LBrace,
    /// `}`
    RBrace,
    /// End of input.
    Eof,
}

impl Tok {
    /// How the token reads in an error message.
    pub(crate) fn describe(&self) -> String {
        match self {
            Tok::Section(name) => format!("section header [{name}]"),
            Tok::Word(word) => format!("`{}`", truncate(word)),
            Tok::Str(_) | Tok::UnterminatedStr(_) => "a quoted string".to_string(),
            Tok::Equals => "'='".to_string(),
            Tok::Comma => "','".to_string(),
            Tok::Semicolon => "';'".to_string(),
            Tok::LBrace => "'{'".to_string(),
            Tok::RBrace => "'}'".to_string(),
            Tok::Eof => "end of file".to_string(),
        }
    }
}

fn truncate(text: &str) -> String {
    const MAX: usize = 40;
    if text.chars().count() <= MAX {
        text.to_string()
    } else {
        let mut cut: String = text.chars().take(MAX).collect();
        cut.push('…');
        cut
    }
}

/// A token, the position of its first character and the position just after its last.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct Token {
    pub(crate) tok: Tok,
    pub(crate) span: Span,
    pub(crate) end: Span,
}

/// A `$` comment: its text from the `$` to the end of the line, trailing whitespace removed.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct Comment {
    pub(crate) span: Span,
    pub(crate) text: String,
}

/// Splits decoded EDS text into [`Token`]s.
pub(crate) struct Lexer<'a> {
    chars: Peekable<Chars<'a>>,
    line: u32,
    column: u32,
    errors: Vec<ParseError>,
    comments: Vec<Comment>,
}

/// Whitespace between tokens: ASCII spaces and line breaks, DOS end-of-file (0x1A) and NUL.
pub(crate) fn is_space(c: char) -> bool {
    matches!(c, ' ' | '\t' | '\n' | '\r' | '\u{0b}' | '\u{0c}' | '\u{1a}' | '\0')
}

fn ends_word(c: char) -> bool {
    is_space(c) || matches!(c, '[' | '=' | ',' | ';' | '"' | '$' | '{' | '}')
}

impl<'a> Lexer<'a> {
    pub(crate) fn new(text: &'a str) -> Lexer<'a> {
        Lexer { chars: text.chars().peekable(), line: 1, column: 1, errors: Vec::new(), comments: Vec::new() }
    }

    /// Comments found so far, in file order.
    pub(crate) fn take_comments(&mut self) -> Vec<Comment> {
        std::mem::take(&mut self.comments)
    }

    /// Errors found so far, in the order found.
    pub(crate) fn take_errors(&mut self) -> Vec<ParseError> {
        std::mem::take(&mut self.errors)
    }

    fn span(&self) -> Span {
        Span { line: self.line, column: self.column }
    }

    fn peek(&mut self) -> Option<char> {
        self.chars.peek().copied()
    }

    /// Consumes one character; a line break (`\n`, `\r\n`, lone `\r`) is returned as `\n`.
    fn bump(&mut self) -> Option<char> {
        let c = self.chars.next()?;
        match c {
            '\r' => {
                if self.peek() == Some('\n') {
                    self.chars.next();
                }
                self.newline();
                Some('\n')
            }
            '\n' => {
                self.newline();
                Some('\n')
            }
            _ => {
                self.column = self.column.saturating_add(1);
                Some(c)
            }
        }
    }

    fn newline(&mut self) {
        self.line = self.line.saturating_add(1);
        self.column = 1;
    }

    fn skip_trivia(&mut self) {
        while let Some(c) = self.peek() {
            if is_space(c) {
                self.bump();
            } else if c == '$' {
                let span = self.span();
                let mut text = String::new();
                while let Some(c) = self.peek() {
                    if c == '\n' || c == '\r' {
                        break;
                    }
                    text.push(c);
                    self.bump();
                }
                text.truncate(text.trim_end_matches(is_space).len());
                self.comments.push(Comment { span, text });
            } else {
                break;
            }
        }
    }

    /// The next token; [`Tok::Eof`] forever at the end.
    pub(crate) fn next_token(&mut self) -> Token {
        self.skip_trivia();
        let span = self.span();
        let Some(c) = self.peek() else {
            return Token { tok: Tok::Eof, span, end: span };
        };
        let tok = match c {
            '[' => {
                self.bump();
                self.section(span)
            }
            '"' => {
                self.bump();
                self.string(span)
            }
            '=' | ',' | ';' | '{' | '}' => {
                self.bump();
                match c {
                    '=' => Tok::Equals,
                    ',' => Tok::Comma,
                    ';' => Tok::Semicolon,
                    '{' => Tok::LBrace,
                    _ => Tok::RBrace,
                }
            }
            _ => {
                let mut word = String::new();
                while let Some(c) = self.peek() {
                    if ends_word(c) {
                        break;
                    }
                    word.push(c);
                    self.bump();
                }
                Tok::Word(word)
            }
        };
        Token { tok, span, end: self.span() }
    }

    fn section(&mut self, start: Span) -> Tok {
        let mut name = String::new();
        loop {
            match self.peek() {
                Some(']') => {
                    self.bump();
                    break;
                }
                None | Some('\n' | '\r') => {
                    self.errors.push(ParseError::new(start, SyntaxError::UnterminatedSection));
                    break;
                }
                Some(c) => {
                    name.push(c);
                    self.bump();
                }
            }
        }
        Tok::Section(name.trim_matches(is_space).to_string())
    }

    fn string(&mut self, start: Span) -> Tok {
        let mut text = String::new();
        let mut checked_line_break = false;
        loop {
            if !checked_line_break && matches!(self.peek(), Some('\n' | '\r')) {
                checked_line_break = true;
                if !self.string_continues() {
                    self.errors.push(ParseError::new(start, SyntaxError::UnterminatedString));
                    return Tok::UnterminatedStr(text);
                }
            }
            match self.bump() {
                None => {
                    self.errors.push(ParseError::new(start, SyntaxError::UnterminatedString));
                    return Tok::UnterminatedStr(text);
                }
                Some('"') => break,
                Some('\\') => match self.peek() {
                    Some('\\') => {
                        self.bump();
                        text.push('\\');
                    }
                    Some('"') => {
                        self.bump();
                        text.push('"');
                    }
                    Some('n') => {
                        self.bump();
                        text.push('\n');
                    }
                    Some('t') => {
                        self.bump();
                        text.push('\t');
                    }
                    Some('r') => {
                        self.bump();
                        text.push('\r');
                    }
                    Some('x') => self.hex_escape(&mut text),
                    _ => text.push('\\'),
                },
                Some(c) => text.push(c),
            }
        }
        Tok::Str(text)
    }

    /// At a line break inside a string: whether the text after it can be the rest of the string
    /// (see the module docs). Looks ahead without consuming.
    fn string_continues(&self) -> bool {
        let mut ahead = self.chars.clone();
        let mut line = String::new();
        // Skip the rest of the first line: it is empty, the break is next.
        let mut first = true;
        loop {
            let next = ahead.next();
            if let Some(c) = next.filter(|c| !matches!(c, '\n' | '\r')) {
                line.push(c);
                continue;
            }
            if !std::mem::take(&mut first) {
                if starts_section_or_entry(&line) {
                    return false;
                }
                if let Some(quote) = closing_quote(&line) {
                    let after = &line[quote + 1..];
                    let trimmed = after.trim_start_matches(is_space);
                    return trimmed.is_empty()
                        || trimmed.starts_with([',', ';', '}', '$'])
                        || trimmed.starts_with('"') && trimmed.len() < after.len();
                }
            }
            if next.is_none() {
                return false; // no closing quote at all
            }
            line.clear();
        }
    }

    /// `\xHH` (one or two hex digits) after the backslash; `\x` without a digit stays literal.
    fn hex_escape(&mut self, text: &mut String) {
        let mut ahead = self.chars.clone();
        ahead.next(); // the 'x'
        let digits: String = ahead.take_while(char::is_ascii_hexdigit).take(2).collect();
        match u8::from_str_radix(&digits, 16) {
            Ok(byte) => {
                self.bump();
                for _ in 0..digits.len() {
                    self.bump();
                }
                text.push(char::from(byte));
            }
            Err(_) => text.push('\\'),
        }
    }
}

/// Whether `line` is a section header (`[Name]`, then only a comment) or starts an entry
/// (`Keyword =`).
fn starts_section_or_entry(line: &str) -> bool {
    let line = line.trim_start_matches(is_space);
    if let Some(name) = line.strip_prefix('[') {
        return name.split_once(']').is_some_and(|(name, rest)| {
            let rest = rest.trim_start_matches(is_space);
            !name.contains('"') && (rest.is_empty() || rest.starts_with('$'))
        });
    }
    let keyword_end = line.find(|c: char| !(c.is_ascii_alphanumeric() || c == '_')).unwrap_or(line.len());
    keyword_end > 0 && line[keyword_end..].trim_start_matches(is_space).starts_with('=')
}

/// The byte index of the first `"` of `line` that is not escaped by a backslash.
fn closing_quote(line: &str) -> Option<usize> {
    let mut escaped = false;
    for (i, c) in line.char_indices() {
        match c {
            '"' if !escaped => return Some(i),
            '\\' => escaped = !escaped,
            _ => escaped = false,
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    fn toks(text: &str) -> Vec<Tok> {
        let mut lexer = Lexer::new(text);
        let mut out = Vec::new();
        loop {
            let token = lexer.next_token();
            if token.tok == Tok::Eof {
                break;
            }
            out.push(token.tok);
        }
        assert!(lexer.take_errors().is_empty());
        out
    }

    fn w(s: &str) -> Tok {
        Tok::Word(s.to_string())
    }

    fn s(s: &str) -> Tok {
        Tok::Str(s.to_string())
    }

    #[rstest]
    #[case::section("[Device Classification]", vec![Tok::Section("Device Classification".into())])]
    #[case::entry("VendCode = 283;", vec![w("VendCode"), Tok::Equals, w("283"), Tok::Semicolon])]
    #[case::comment_to_end_of_line("a $ b, c;\n;", vec![w("a"), Tok::Semicolon])]
    #[case::dollar_inside_string("\"$Id: $\"", vec![s("$Id: $")])]
    #[case::string_spanning_lines("\"one\ntwo\"", vec![s("one\ntwo")])]
    #[case::crlf_in_string("\"one\r\ntwo\"", vec![s("one\ntwo")])]
    #[case::escapes(r#""a\"b\\c\td\x41\q""#, vec![s("a\"b\\c\tdA\\q")])]
    #[case::lone_hex_escape(r#""\xz""#, vec![s("\\xz")])]
    #[case::empty_fields(",,;", vec![Tok::Comma, Tok::Comma, Tok::Semicolon])]
    #[case::braces("{1,2}", vec![Tok::LBrace, w("1"), Tok::Comma, w("2"), Tok::RBrace])]
    #[case::hex_word("0X00c6", vec![w("0X00c6")])]
    #[case::dos_eof("a\u{1a}", vec![w("a")])]
    fn lexes(#[case] text: &str, #[case] expected: Vec<Tok>) {
        assert_eq!(toks(text), expected);
    }

    #[test]
    fn positions_count_lines_and_columns() {
        let mut lexer = Lexer::new("[File]\r\n  DescText = \"x\";\r  Revision");
        let spans: Vec<Span> = std::iter::from_fn(|| {
            let t = lexer.next_token();
            (t.tok != Tok::Eof).then_some(t.span)
        })
        .collect();
        assert_eq!(
            spans,
            vec![
                Span::new(1, 1),
                Span::new(2, 3),
                Span::new(2, 12),
                Span::new(2, 14),
                Span::new(2, 17),
                Span::new(3, 3)
            ]
        );
    }

    #[rstest]
    #[case::closed_on_a_later_line("\"one\ntwo\";", None)]
    #[case::closed_before_a_comma("\"one\n two\", 3", None)]
    #[case::closed_then_adjacent_string("\"one\ntwo\" \"three\"", None)]
    #[case::bracket_line_that_is_no_header("\"one\n[two\"}", None)]
    #[case::next_line_is_an_entry("\"one\nB = 1;", Some("one"))]
    #[case::next_line_is_a_section("\"one\n\n[Device]  $ id\n", Some("one"))]
    #[case::next_quote_opens_a_string("\"one,\n  \"\",\n  \"help\";", Some("one,"))]
    #[case::no_closing_quote("\"one\n two", Some("one"))]
    fn a_string_spanning_lines_is_closed_only_when_the_rest_fits(
        #[case] text: &str,
        #[case] unterminated: Option<&str>,
    ) {
        let mut lexer = Lexer::new(text);
        let first = lexer.next_token().tok;
        while lexer.next_token().tok != Tok::Eof {}
        let errors = lexer.take_errors();
        match unterminated {
            None => assert!(matches!(first, Tok::Str(_)) && errors.is_empty(), "{first:?} {errors:?}"),
            Some(cut) => {
                assert_eq!(first, Tok::UnterminatedStr(cut.to_string()));
                assert_eq!(errors, vec![ParseError::new(Span::START, SyntaxError::UnterminatedString)]);
            }
        }
    }

    #[test]
    fn an_unterminated_string_ends_at_its_line_and_lexing_goes_on() {
        let mut lexer = Lexer::new("A = \"abc\nB = 1;");
        let toks: Vec<Tok> =
            std::iter::from_fn(|| Some(lexer.next_token().tok).filter(|t| *t != Tok::Eof)).collect();
        assert_eq!(
            toks,
            vec![
                w("A"),
                Tok::Equals,
                Tok::UnterminatedStr("abc".into()),
                w("B"),
                Tok::Equals,
                w("1"),
                Tok::Semicolon
            ]
        );
    }

    #[test]
    fn keeps_comments_with_positions() {
        let mut lexer = Lexer::new("$ top \u{a0} \n[S] $ s\u{92}\r\nA = \"$ no\"; $ end  ");
        while lexer.next_token().tok != Tok::Eof {}
        let comments: Vec<(Span, String)> =
            lexer.take_comments().into_iter().map(|c| (c.span, c.text)).collect();
        assert_eq!(
            comments,
            vec![
                (Span::new(1, 1), "$ top \u{a0}".to_string()),
                (Span::new(2, 5), "$ s\u{92}".to_string()),
                (Span::new(3, 13), "$ end".to_string()),
            ]
        );
    }

    #[rstest]
    #[case::unterminated_string("x = \"abc", SyntaxError::UnterminatedString, Span::new(1, 5))]
    #[case::unterminated_section("[File\nA = 1;", SyntaxError::UnterminatedSection, Span::new(1, 1))]
    fn reports_errors(#[case] text: &str, #[case] kind: SyntaxError, #[case] span: Span) {
        let mut lexer = Lexer::new(text);
        while lexer.next_token().tok != Tok::Eof {}
        assert_eq!(lexer.take_errors(), vec![ParseError::new(span, kind)]);
    }
}
