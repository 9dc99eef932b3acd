//! Bytes to text: UTF-8 when the file is valid UTF-8, Latin-1 (ISO 8859-1) otherwise.
//!
//! EDS files predate Unicode; most are ASCII and many carry Latin-1 bytes (`°`, `µ`, umlauts in
//! vendor names). Every byte sequence decodes, so decoding never fails except on the size limit.

use crate::diag::Span;
use crate::error::{ParseError, SyntaxError};
use crate::limits::MAX_INPUT_BYTES;
use std::borrow::Cow;

/// The character encoding [`decode`] found.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Encoding {
    /// Valid UTF-8 (which includes plain ASCII).
    Utf8,
    /// Not valid UTF-8: every byte was taken as the Latin-1 character of the same code.
    Latin1,
}

/// Decodes `bytes` as UTF-8 when valid, else as Latin-1; a leading UTF-8 byte-order mark is
/// dropped.
///
/// # Errors
///
/// [`SyntaxError::TooLarge`] when `bytes` is longer than [`MAX_INPUT_BYTES`].
pub fn decode(bytes: &[u8]) -> Result<(Cow<'_, str>, Encoding), ParseError> {
    if bytes.len() > MAX_INPUT_BYTES {
        return Err(ParseError::new(
            Span::START,
            SyntaxError::TooLarge { size: bytes.len(), limit: MAX_INPUT_BYTES },
        ));
    }
    match std::str::from_utf8(bytes) {
        Ok(text) => Ok((Cow::Borrowed(text.strip_prefix('\u{feff}').unwrap_or(text)), Encoding::Utf8)),
        Err(_) => Ok((Cow::Owned(bytes.iter().map(|&b| char::from(b)).collect()), Encoding::Latin1)),
    }
}

/// Encodes `text` as Latin-1 for tools that expect single-byte EDS files.
///
/// # Errors
///
/// The first character above U+00FF, which Latin-1 cannot represent.
pub fn encode_latin1(text: &str) -> Result<Vec<u8>, char> {
    text.chars().map(|c| u8::try_from(u32::from(c)).map_err(|_| c)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    #[rstest]
    #[case::ascii(b"[File]", "[File]", Encoding::Utf8)]
    #[case::utf8_degree("°C".as_bytes(), "°C", Encoding::Utf8)]
    #[case::latin1_degree(b"\xb0C", "°C", Encoding::Latin1)]
    #[case::latin1_umlaut(b"M\xfcller", "Müller", Encoding::Latin1)]
    #[case::bom(b"\xef\xbb\xbf[File]", "[File]", Encoding::Utf8)]
    fn decodes(#[case] bytes: &[u8], #[case] text: &str, #[case] encoding: Encoding) {
        let (decoded, found) = decode(bytes).unwrap();
        assert_eq!(decoded, text);
        assert_eq!(found, encoding);
    }

    #[test]
    fn rejects_oversized_input() {
        let big = vec![b' '; MAX_INPUT_BYTES + 1];
        let err = decode(&big).unwrap_err();
        assert!(matches!(err.kind, SyntaxError::TooLarge { .. }));
    }

    #[test]
    fn latin1_round_trip() {
        assert_eq!(encode_latin1("Müller °C").unwrap(), b"M\xfcller \xb0C");
        assert_eq!(encode_latin1("€"), Err('€'));
    }
}
