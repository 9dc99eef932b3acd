//! Positions and diagnostics: where something is in the source, how bad it is, and which rule
//! found it.

use serde::Serialize;
use std::fmt;

/// A position in the decoded source text: 1-based line and 1-based column (in characters, a tab
/// counts as one column).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
pub struct Span {
    /// Line, starting at 1.
    pub line: u32,
    /// Column in characters, starting at 1.
    pub column: u32,
}

impl Span {
    /// The first character of a file.
    pub const START: Span = Span { line: 1, column: 1 };

    /// A span at `line`, `column`.
    pub const fn new(line: u32, column: u32) -> Span {
        Span { line, column }
    }
}

impl fmt::Display for Span {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}", self.line, self.column)
    }
}

/// How serious a [`Diagnostic`] is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Severity {
    /// The file is usable but questionable: a tool may misread it or a user may be surprised.
    Warning,
    /// The file is wrong: a configuration tool or scanner will reject it or misconfigure the device.
    Error,
}

impl fmt::Display for Severity {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Severity::Warning => "warning",
            Severity::Error => "error",
        })
    }
}

/// The rule a [`Diagnostic`] comes from; its kebab-case name ([`Rule::as_str`]) is stable and
/// printed in brackets (`error[duplicate-entry]`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Rule {
    /// The text is not well-formed EDS (lexer or parser error).
    Syntax,
    /// The input exceeds a size limit of the parser ([`crate::limits`]).
    Limit,
    /// A required section is missing.
    MissingSection,
    /// A required keyword is missing from its section.
    MissingKey,
    /// A section appears more than once.
    DuplicateSection,
    /// A keyword (or a parameter, enum or group number) appears more than once in a section.
    DuplicateEntry,
    /// A value does not have the form its keyword requires (not a number, out of its range, ...).
    InvalidValue,
    /// An entry has fewer (or, for single values, more) fields than its keyword requires.
    FieldCount,
    /// A keyword the model does not know, in a section it does know (kept as is).
    UnknownKeyword,
    /// A section the model does not know and that is not a CIP object class section (kept as is).
    UnknownSection,
    /// A group, enum or scaling link refers to a parameter that does not exist.
    UndefinedParam,
    /// A parameter's minimum is greater than its maximum.
    RangeOrder,
    /// A parameter's default lies outside `min..=max`.
    DefaultOutOfRange,
    /// A value does not fit the parameter's data type.
    TypeRange,
    /// A data size does not match the size of the data type code.
    DataSize,
    /// A data type code that is not a CIP elementary type.
    UnknownDataType,
    /// An enumerated value lies outside the parameter's `min..=max`.
    EnumOutOfRange,
    /// Enum strings and the descriptor's "supports enumerated strings" bit disagree.
    EnumDescriptor,
    /// A legacy `[EnumPar]` list does not have one string per value of `min..=max`.
    EnumCount,
    /// A parameter has enum strings in both dialects (`EnumN` and `[EnumPar]`).
    EnumConflict,
    /// A group's declared parameter count differs from the parameters it lists, or a group lists
    /// a parameter twice.
    GroupCount,
    /// A path size differs from the number of bytes in the path.
    PathSize,
    /// An I/O entry's bit count does not fit its byte size.
    IoSize,
    /// A connection's default input or output names an `InputN`/`OutputN` that does not exist.
    IoReference,
    /// A connection mask sets a reserved bit (4–15), combines change of state with cyclic, or
    /// disagrees with another connection's mask or with the entries it governs.
    ConnectionMask,
    /// The bit-strobe connection's default input is larger than a strobe response (8 bytes).
    StrobeSize,
    /// Parameter scaling that cannot work (divisor 0).
    Scaling,
    /// A reserved field that is not 0.
    Reserved,
    /// `[Device Classification]` does not name DeviceNet.
    Classification,
    /// A string value written without quotes.
    UnquotedString,
}

impl Rule {
    /// The stable kebab-case name of the rule.
    pub const fn as_str(self) -> &'static str {
        match self {
            Rule::Syntax => "syntax",
            Rule::Limit => "limit",
            Rule::MissingSection => "missing-section",
            Rule::MissingKey => "missing-key",
            Rule::DuplicateSection => "duplicate-section",
            Rule::DuplicateEntry => "duplicate-entry",
            Rule::InvalidValue => "invalid-value",
            Rule::FieldCount => "field-count",
            Rule::UnknownKeyword => "unknown-keyword",
            Rule::UnknownSection => "unknown-section",
            Rule::UndefinedParam => "undefined-param",
            Rule::RangeOrder => "range-order",
            Rule::DefaultOutOfRange => "default-out-of-range",
            Rule::TypeRange => "type-range",
            Rule::DataSize => "data-size",
            Rule::UnknownDataType => "unknown-data-type",
            Rule::EnumOutOfRange => "enum-out-of-range",
            Rule::EnumDescriptor => "enum-descriptor",
            Rule::EnumCount => "enum-count",
            Rule::EnumConflict => "enum-conflict",
            Rule::GroupCount => "group-count",
            Rule::PathSize => "path-size",
            Rule::IoSize => "io-size",
            Rule::IoReference => "io-reference",
            Rule::ConnectionMask => "connection-mask",
            Rule::StrobeSize => "strobe-size",
            Rule::Scaling => "scaling",
            Rule::Reserved => "reserved",
            Rule::Classification => "classification",
            Rule::UnquotedString => "unquoted-string",
        }
    }
}

impl fmt::Display for Rule {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// One finding about an EDS file, with its position.
///
/// Displays as `LINE:COLUMN: SEVERITY[RULE]: MESSAGE`; [`crate::Report`] prefixes the file name.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Diagnostic {
    /// Error or warning.
    pub severity: Severity,
    /// The rule that produced it.
    pub rule: Rule,
    /// Where in the file (the entry, field or section concerned).
    pub span: Span,
    /// What is wrong, in words.
    pub message: String,
}

impl Diagnostic {
    /// An error diagnostic.
    pub fn error(rule: Rule, span: Span, message: impl Into<String>) -> Diagnostic {
        Diagnostic { severity: Severity::Error, rule, span, message: message.into() }
    }

    /// A warning diagnostic.
    pub fn warning(rule: Rule, span: Span, message: impl Into<String>) -> Diagnostic {
        Diagnostic { severity: Severity::Warning, rule, span, message: message.into() }
    }

    /// `true` for [`Severity::Error`].
    pub fn is_error(&self) -> bool {
        self.severity == Severity::Error
    }
}

impl fmt::Display for Diagnostic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}[{}]: {}", self.span, self.severity, self.rule, self.message)
    }
}
