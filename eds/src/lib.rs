//! # eds
//!
//! DeviceNet Electronic Data Sheets (EDS): read real vendor files, check them, write them
//! deterministically, and generate the EDS of our converter from its device description. The
//! `dnet-eds` command-line tool (crate `eds-tool`) is a thin shell over this library; its
//! `check-device`, a device on the bus against an EDS, lives there too, so this file-format crate
//! depends on no bus crate.
//!
//! ## Layers
//!
//! | layer | module | input → output |
//! |---|---|---|
//! | decoding | [`text`] | bytes → text (UTF-8, else Latin-1), size capped |
//! | lexer | `lexer` (private) | text → tokens with line/column; `$` comments, quoted strings |
//! | raw sections | [`raw`] | tokens → [`RawEds`]: sections, entries, fields, every position kept |
//! | comments | [`comments`] | `$` comments → [`Comments`] attached to sections and entries by name |
//! | typed model | [`model`] | [`RawEds`] → [`Eds`]: identity, I/O, parameters, enums, groups, unknowns kept |
//! | checks | [`mod@check`] | [`Eds`] + [`RawEds`] → [`Report`] of [`Diagnostic`]s, errors vs warnings |
//! | writer | [`mod@write`] | [`Eds`] (+ [`Comments`]) → EDS text, deterministic; [`format()`] for files |
//! | generator | [`mod@generate`] | device description ([`slave_fw::description`]) → [`Eds`] → text |
//!
//! Each layer only depends on the ones above it; each can be used alone (a tool that only needs
//! sections can stop at [`RawEds`]). Only the generator depends on the rest of the workspace: on
//! `slave-fw` (the description and the converter's objects).
//!
//! ## Dialect coverage
//!
//! Sections and keywords match ignoring case; `$` comments run to the end of the line outside
//! strings; strings may span lines and adjacent strings are joined; entries span lines up to
//! `;`; fields may be empty; integers are decimal or `0x`/`0X` hex; vendor keywords
//! (`283_Name`) and unknown sections are kept; both enum dialects (`EnumN` in `[Params]`, legacy
//! `[EnumPar]`) are read; every optional section may be missing; non-UTF-8 files are read as
//! Latin-1, and [`format()`] writes them back as Latin-1 with their comments in place.
//!
//! ## Quick start
//!
//! ```
//! let text = b"[Device]\nVendCode = 283;\nProdName = \"Demo\";\n";
//! let eds = eds::parse(text)?;
//! assert_eq!(eds.device.as_ref().and_then(|d| d.vend_code), Some(283));
//!
//! let report = eds::check(text);
//! assert!(report.has_errors()); // [File] and several [Device] keys are missing
//!
//! let written = eds::Writer::new().write(&eds);
//! assert_eq!(eds::parse_str(&written)?, eds);
//! # Ok::<(), eds::ParseError>(())
//! ```
//!
//! Generating the converter's EDS and checking it:
//!
//! ```
//! use eds::generate::{generate_text, GenerateOptions};
//! use slave_fw::description::DeviceDescription;
//!
//! let text = generate_text(&DeviceDescription::reference(), &GenerateOptions::default());
//! assert!(!eds::check_str(&text).has_errors());
//! let eds = eds::parse_str(&text)?;
//! assert_eq!(eds.io_info.as_ref().and_then(|io| io.inputs[&1].size), Some(18));
//! # Ok::<(), eds::ParseError>(())
//! ```
//!
//! ## I/O connections
//!
//! The generated `[IO_Info]` announces what the node offers (docs/src/reference/io-connections.md): poll (the
//! default), bit-strobe, change of state and cyclic, with the compatibility masks of the
//! DeviceNet files in `../shared/eds-corpus/`; the strobe response, min(P, 8) bytes of the input
//! assembly, is an input entry of its own when the input is larger. [`check()`] checks those
//! entries (masks, references, the 8-byte strobe limit: [`mod@check`]). A DeviceNet EDS has no
//! `[Connection Manager]` (no file of the corpus has one; it describes EtherNet/IP and ControlNet
//! connections), so none is generated, and one found in a file is kept unchecked.
//!
//! ## No-panic contract
//!
//! Every entry point accepts any bytes and returns a value or an error; no input makes the
//! library panic, recurse without bound or allocate without bound ([`limits`]). A property test
//! feeds arbitrary bytes through every layer. The generator takes a description validated by
//! `slave_fw` and does only checked or saturating arithmetic on it.

pub mod check;
pub mod comments;
pub mod diag;
pub mod error;
pub mod generate;
mod lexer;
pub mod limits;
pub mod model;
pub mod raw;
pub mod summary;
pub mod text;
pub mod value;
pub mod write;

pub use check::{check, check_file, check_str, Report};
pub use comments::Comments;
pub use diag::{Diagnostic, Rule, Severity, Span};
pub use error::{EdsError, ParseError, SyntaxError};
pub use generate::{generate, generate_text, GenerateOptions};
pub use model::{Eds, EnumDialect, EnumEntry, Param, ParamEnum};
pub use raw::{Field, FieldValue, RawEds, RawEntry, RawSection};
pub use summary::Summary;
pub use value::{AttributePath, ConnectionMask, DataType, Descriptor, LinkPath, Value};
pub use write::Writer;

use std::path::Path;

/// Parses an EDS given as bytes (UTF-8, else Latin-1) into the typed model.
///
/// Only syntax errors fail; problems in content (missing keys, bad values, ranges) are left to
/// [`check()`], and untypeable entries are kept in the model's `other` lists.
///
/// # Errors
///
/// The first syntax error, or a size limit.
pub fn parse(bytes: &[u8]) -> Result<Eds, ParseError> {
    let (text, _) = text::decode(bytes)?;
    parse_str(&text)
}

/// Parses decoded EDS text into the typed model; see [`parse`].
///
/// # Errors
///
/// The first syntax error.
pub fn parse_str(text: &str) -> Result<Eds, ParseError> {
    let raw = RawEds::parse(text)?;
    Ok(Eds::from_raw(&raw).0)
}

/// Rewrites EDS bytes in the [`Writer`]'s canonical layout (what `dnet-eds format` prints), with
/// the file's `$` comments in place ([`comments`]) and in the file's own encoding: a Latin-1
/// file stays Latin-1, so its bytes 0x80–0xFF in strings and comments come back unchanged; a
/// UTF-8 file stays UTF-8 (a byte-order mark is dropped). Formatting the output again gives the
/// same bytes, and the output parses to the same model.
///
/// # Errors
///
/// The first syntax error, or a size limit.
pub fn format(bytes: &[u8]) -> Result<Vec<u8>, ParseError> {
    let (text, encoding) = text::decode(bytes)?;
    let (raw, comments) = RawEds::parse_with_comments(&text)?;
    let eds = Eds::from_raw(&raw).0;
    let written = Writer::new().write_with_comments(&eds, &comments);
    Ok(match encoding {
        text::Encoding::Utf8 => written.into_bytes(),
        // Every character is from the input (so at most U+00FF) or ASCII from the writer; the
        // fallback to UTF-8 is never taken.
        text::Encoding::Latin1 => text::encode_latin1(&written).unwrap_or_else(|_| written.into_bytes()),
    })
}

/// [`format()`] of the EDS file at `path`; errors name the file.
///
/// # Errors
///
/// As [`read_file`].
pub fn format_file(path: impl AsRef<Path>) -> Result<Vec<u8>, EdsError> {
    let path = path.as_ref();
    let bytes = read_bytes(path)?;
    format(&bytes).map_err(|e| EdsError::Parse(e.with_file(path)))
}

/// Reads and parses the EDS file at `path`; errors name the file.
///
/// # Errors
///
/// [`EdsError::Io`] when the file cannot be read, [`EdsError::Parse`] (with the file name, line
/// and column) when it is not well-formed.
pub fn read_file(path: impl AsRef<Path>) -> Result<Eds, EdsError> {
    let path = path.as_ref();
    let bytes = read_bytes(path)?;
    parse(&bytes).map_err(|e| EdsError::Parse(e.with_file(path)))
}

/// Reads at most [`limits::MAX_INPUT_BYTES`] + 1 bytes, so a huge file is refused without being
/// loaded whole.
pub(crate) fn read_bytes(path: &Path) -> Result<Vec<u8>, EdsError> {
    use std::io::Read;
    let io = |source| EdsError::Io { path: path.to_path_buf(), source };
    let file = std::fs::File::open(path).map_err(io)?;
    let mut bytes = Vec::new();
    let cap = u64::try_from(limits::MAX_INPUT_BYTES).unwrap_or(u64::MAX).saturating_add(1);
    file.take(cap).read_to_end(&mut bytes).map_err(io)?;
    Ok(bytes)
}
