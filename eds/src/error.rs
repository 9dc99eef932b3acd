//! Error types of the parser and of file reading (`thiserror`, with file, line and column).

use crate::diag::Span;
use std::fmt;
use std::path::PathBuf;

/// What is wrong with the text at a [`ParseError`]'s position.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum SyntaxError {
    /// The input is larger than [`crate::limits::MAX_INPUT_BYTES`].
    #[error("input is {size} bytes, more than the limit of {limit} bytes")]
    TooLarge {
        /// Size of the input in bytes.
        size: usize,
        /// The limit in bytes.
        limit: usize,
    },
    /// More sections, entries or fields than the parser's limits allow.
    #[error("more than {limit} {what}")]
    TooMany {
        /// What was counted ("sections", "entries", "fields").
        what: &'static str,
        /// The limit.
        limit: usize,
    },
    /// `{` groups nested deeper than [`crate::limits::MAX_NESTING`].
    #[error("'{{' groups nested more than {0} deep")]
    TooDeep(usize),
    /// A `"` with no closing `"`: none before the end of the file, or the text after the string's
    /// first line break cannot be its rest (see the lexer rules in [`crate::raw`]). The position
    /// is the opening quote.
    #[error("string is not terminated: the '\"' here has no closing '\"'")]
    UnterminatedString,
    /// A `[` with no `]` on the same line.
    #[error("section header has no closing ']' on its line")]
    UnterminatedSection,
    /// `[]`.
    #[error("section name is empty")]
    EmptySectionName,
    /// An entry before the first `[Section]` header.
    #[error("entry `{0}` appears before any [Section] header")]
    EntryOutsideSection(String),
    /// Something other than a keyword where an entry should start.
    #[error("expected a keyword, found {0}")]
    ExpectedKeyword(String),
    /// A keyword not followed by `=`.
    #[error("expected '=' after keyword `{keyword}`, found {found}")]
    ExpectedEquals {
        /// The keyword.
        keyword: String,
        /// What was found instead.
        found: String,
    },
    /// A keyword containing characters other than letters, digits and `_`.
    #[error("invalid keyword `{0}`: keywords are made of letters, digits and '_'")]
    InvalidKeyword(String),
    /// An entry not terminated by `;` (before the next keyword, section or end of file). The
    /// position is just after the entry's last value, where the `;` belongs.
    #[error("missing ';' after entry `{0}`")]
    MissingSemicolon(String),
    /// A token that cannot appear in a value.
    #[error("unexpected {found} in the value of `{keyword}`")]
    UnexpectedToken {
        /// The entry's keyword.
        keyword: String,
        /// What was found.
        found: String,
    },
    /// Unquoted text and a quoted string in one field.
    #[error("unquoted text and a quoted string in one field of `{0}` (missing ',')")]
    MixedField(String),
    /// A `{` group not closed by `}`.
    #[error("'{{' group in `{0}` is not closed by '}}'")]
    UnclosedBrace(String),
    /// A `}` with no `{`.
    #[error("'}}' without a matching '{{' in `{0}`")]
    UnmatchedBrace(String),
}

/// A syntax error with its position and, when known, its file.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub struct ParseError {
    /// The file the text came from, when it came from a file.
    pub file: Option<PathBuf>,
    /// Line and column of the error.
    pub span: Span,
    /// What is wrong.
    pub kind: SyntaxError,
}

impl ParseError {
    /// An error at `span` without a file name.
    pub fn new(span: Span, kind: SyntaxError) -> ParseError {
        ParseError { file: None, span, kind }
    }

    /// The same error, attributed to `file`.
    pub fn with_file(mut self, file: impl Into<PathBuf>) -> ParseError {
        self.file = Some(file.into());
        self
    }
}

impl fmt::Display for ParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(file) = &self.file {
            write!(f, "{}:", file.display())?;
        }
        write!(f, "{}: {}", self.span, self.kind)
    }
}

/// Reading an EDS file failed.
#[derive(Debug, thiserror::Error)]
pub enum EdsError {
    /// The file could not be read.
    #[error("cannot read {}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// The file is not well-formed EDS.
    #[error(transparent)]
    Parse(#[from] ParseError),
}
