//! Hard limits that bound the parser's memory on any input.
//!
//! Real EDS files are a few kilobytes to a few megabytes (large modular devices); every limit is
//! far above that and keeps the worst case to a few hundred megabytes of model at most.

/// Largest input accepted, in bytes (16 MiB).
pub const MAX_INPUT_BYTES: usize = 16 * 1024 * 1024;
/// Most sections in one file.
pub const MAX_SECTIONS: usize = 10_000;
/// Most entries in one file, over all sections.
pub const MAX_ENTRIES: usize = 500_000;
/// Most fields in one file, over all entries (an empty field counts).
pub const MAX_FIELDS: usize = 2_000_000;
/// Deepest nesting of `{ }` groups.
pub const MAX_NESTING: usize = 16;
