//! The lexer: decoded text to tokens, with line and column.
//!
//! EDS lexical rules handled here:
//!
//! - `$` starts a comment that runs to the end of the line, except inside a quoted string;
//! - `"..."` strings may span lines (a line break inside is kept as `\n`) and understand the
//!   escapes `\\`, `\"`, `\n`, `\t`, `\r` and `\xHH`; an unknown escape is kept literally (so a
//!   Windows path such as `"C:\eds\x.ico"` survives); adjacent strings are joined by the parser;
//! - `[name]` is a section header; `=`, `,`, `;`, `{`, `}` are punctuation;
//! - everything else up to whitespace or punctuation is a word (keywords, numbers such as `0x00C6`,
//!   dates, unquoted identifiers such as `DeviceNet`);
//! - line breaks are `\n`, `\r\n` or a lone `\r`; DOS end-of-file (0x1A) and NUL count as
//!   whitespace.
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
            Tok::Str(_) => "a quoted string".to_string(),
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

/// A token and the position of its first character.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct Token {
    pub(crate) tok: Tok,
    pub(crate) span: Span,
}

/// Splits decoded EDS text into [`Token`]s.
pub(crate) struct Lexer<'a> {
    chars: Peekable<Chars<'a>>,
    line: u32,
    column: u32,
    errors: Vec<ParseError>,
}

fn is_space(c: char) -> bool {
    c.is_whitespace() || c == '\u{1a}' || c == '\0'
}

fn ends_word(c: char) -> bool {
    is_space(c) || matches!(c, '[' | '=' | ',' | ';' | '"' | '$' | '{' | '}')
}

impl<'a> Lexer<'a> {
    pub(crate) fn new(text: &'a str) -> Lexer<'a> {
        Lexer { chars: text.chars().peekable(), line: 1, column: 1, errors: Vec::new() }
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
                while let Some(c) = self.peek() {
                    if c == '\n' || c == '\r' {
                        break;
                    }
                    self.bump();
                }
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
            return Token { tok: Tok::Eof, span };
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
        Token { tok, span }
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
        Tok::Section(name.trim().to_string())
    }

    fn string(&mut self, start: Span) -> Tok {
        let mut text = String::new();
        loop {
            match self.bump() {
                None => {
                    self.errors.push(ParseError::new(start, SyntaxError::UnterminatedString));
                    break;
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
    #[case::unterminated_string("x = \"abc", SyntaxError::UnterminatedString, Span::new(1, 5))]
    #[case::unterminated_section("[File\nA = 1;", SyntaxError::UnterminatedSection, Span::new(1, 1))]
    fn reports_errors(#[case] text: &str, #[case] kind: SyntaxError, #[case] span: Span) {
        let mut lexer = Lexer::new(text);
        while lexer.next_token().tok != Tok::Eof {}
        assert_eq!(lexer.take_errors(), vec![ParseError::new(span, kind)]);
    }
}
