//! `$` comments, attached to the sections and entries they describe, so that `dnet-eds format`
//! keeps them where the vendor put them.
//!
//! The typed model ([`crate::Eds`]) holds no comments: the writer reorders sections and entries,
//! so a comment is attached to an item and travels with it. The rules, by where the comment is:
//!
//! | where | attached as |
//! |---|---|
//! | lines above the first section, up to the last blank line before it | [`Comments::header`] |
//! | lines above a section header or an entry (after the previous item) | that item's [`Attached::before`] |
//! | after a section header, on its line | the section's [`Attached::end_of_line`] |
//! | on the line an entry starts on (after `;`, or after `=` or a value of a multi-line entry) | the entry's [`Attached::end_of_line`] |
//! | on a later line of a multi-line entry, up to the line of its `;` | [`Attached::fields`], under the index of the field it follows |
//! | lines after the last item | [`Comments::trailer`] |
//!
//! Comment lines keep their text from the `$` to the end of the line, trailing whitespace
//! removed; in the line lists a blank line between two comments is kept as one `""`.
//!
//! The writer puts each back in the same place relative to its item: `before` lines above it,
//! `end_of_line` after a single-line entry's `;` or after the `=` of a multi-line one, field
//! comments at the end of the line holding that field (in place of the comment the writer would
//! generate; several on one line are joined by a space). Read back, every comment lands where it
//! was written, so formatting formatted text changes nothing. Comments whose item the writer does
//! not write (a repeated keyword the model ignores) are written above the trailer.
//!
//! Items are found again by name: sections by their normalized name ([`normalize_name`]) and the
//! how-many-th section of that name, entries by section, keyword (`Param01` is `Param1`) and the
//! how-many-th entry of that keyword.

use crate::diag::Span;
use crate::error::ParseError;
use crate::lexer::Comment;
use crate::model::entry_key;
use crate::raw::{normalize_name, RawEds};
use serde::Serialize;
use std::collections::{BTreeMap, HashMap};

/// The comments of one EDS file; see the [module docs](self).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Comments {
    /// The comment block at the top of the file.
    pub header: Vec<String>,
    /// Section comments by (normalized name, occurrence of that name from 0).
    pub sections: BTreeMap<(String, usize), Attached>,
    /// Entry comments by (normalized section name, entry key, occurrence of that key in
    /// sections of that name from 0).
    pub entries: BTreeMap<(String, String, usize), Attached>,
    /// Comment lines after the last section or entry.
    pub trailer: Vec<String>,
}

/// The comments attached to one section header or entry.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Attached {
    /// Comment lines above the item, `""` for a blank line between two of them.
    pub before: Vec<String>,
    /// The comment at the end of the item's first line.
    pub end_of_line: Option<String>,
    /// Comments on the later lines of a multi-line entry, by the index of the field each follows.
    pub fields: BTreeMap<usize, Vec<String>>,
}

impl Comments {
    /// `true` when the file has no comment at all.
    pub fn is_empty(&self) -> bool {
        self.header.is_empty()
            && self.sections.is_empty()
            && self.entries.is_empty()
            && self.trailer.is_empty()
    }
}

impl Attached {
    fn is_empty(&self) -> bool {
        self.before.is_empty() && self.end_of_line.is_none() && self.fields.is_empty()
    }
}

/// A section header or an entry, where comments can attach.
struct Anchor {
    start: Span,
    /// Just after the entry's `;` or last value; the header's position for a section.
    end: Span,
    /// Positions of an entry's top-level fields.
    fields: Vec<Span>,
    key: Key,
}

enum Key {
    Section((String, usize)),
    Entry((String, String, usize)),
}

impl RawEds {
    /// Parses decoded text and attaches its `$` comments to sections and entries (this module's
    /// docs say how).
    ///
    /// # Errors
    ///
    /// The first syntax error in the text.
    pub fn parse_with_comments(text: &str) -> Result<(RawEds, Comments), ParseError> {
        let parsed = RawEds::parse_all(text);
        if let Some(error) = parsed.errors.into_iter().next() {
            return Err(error);
        }
        let comments = attach(&parsed.raw, &parsed.entry_ends, parsed.comments);
        Ok((parsed.raw, comments))
    }
}

/// Attaches `comments` (in file order) to the sections and entries of `raw`; `ends` holds where
/// each entry ends, in file order.
pub(crate) fn attach(raw: &RawEds, ends: &[Span], comments: Vec<Comment>) -> Comments {
    let anchors = anchors(raw, ends);
    let mut out = Comments::default();
    let mut attached: Vec<Attached> = anchors.iter().map(|_| Attached::default()).collect();
    // Free comment lines, by the anchor they precede (`anchors.len()` for the trailer).
    let mut free: BTreeMap<usize, Vec<Comment>> = BTreeMap::new();
    for comment in comments {
        let at = comment.span;
        let next = anchors.partition_point(|a| a.start < at);
        let Some(prev) = next.checked_sub(1).and_then(|i| anchors.get(i).map(|a| (i, a))) else {
            free.entry(next).or_default().push(comment);
            continue;
        };
        let (i, anchor) = prev;
        let inside = match anchor.key {
            Key::Entry(_) => at < anchor.end || at.line == anchor.end.line,
            Key::Section(_) => at.line == anchor.start.line,
        };
        if !inside {
            free.entry(next).or_default().push(comment);
        } else if at.line == anchor.start.line {
            let slot = &mut attached[i].end_of_line;
            *slot = Some(match slot.take() {
                Some(first) => format!("{first} {}", comment.text),
                None => comment.text,
            });
        } else {
            let field = anchor.fields.partition_point(|f| *f < at).saturating_sub(1);
            attached[i].fields.entry(field).or_default().push(comment.text);
        }
    }
    for (next, block) in free {
        let lines = with_blank_lines(&block);
        if next == 0 && !anchors.is_empty() {
            // Above the first item: the header is everything up to the last blank line, counting
            // one between the block and the item.
            let first = anchors[0].start.line;
            let split = match block.last() {
                Some(last) if first > last.span.line.saturating_add(1) => lines.len(),
                _ => lines.iter().rposition(String::is_empty).unwrap_or(0),
            };
            let mut header = lines;
            let before = header.split_off(split);
            out.header = header;
            while out.header.last().is_some_and(String::is_empty) {
                out.header.pop();
            }
            attached[0].before = before.into_iter().skip_while(String::is_empty).collect();
        } else if next >= anchors.len() {
            if anchors.is_empty() {
                out.header = lines;
            } else {
                out.trailer = lines;
            }
        } else {
            attached[next].before = lines;
        }
    }
    for (anchor, attached) in anchors.into_iter().zip(attached) {
        if attached.is_empty() {
            continue;
        }
        match anchor.key {
            Key::Section(key) => {
                out.sections.insert(key, attached);
            }
            Key::Entry(key) => {
                out.entries.insert(key, attached);
            }
        }
    }
    out
}

/// The comment lines of `block`, with `""` where blank lines separate two of them.
fn with_blank_lines(block: &[Comment]) -> Vec<String> {
    let mut lines = Vec::with_capacity(block.len());
    let mut previous: Option<u32> = None;
    for comment in block {
        if previous.is_some_and(|line| comment.span.line > line.saturating_add(1)) {
            lines.push(String::new());
        }
        lines.push(comment.text.clone());
        previous = Some(comment.span.line);
    }
    lines
}

fn anchors(raw: &RawEds, ends: &[Span]) -> Vec<Anchor> {
    let mut anchors = Vec::new();
    let mut sections: HashMap<String, usize> = HashMap::new();
    let mut entries: HashMap<(String, String), usize> = HashMap::new();
    let mut ends = ends.iter();
    for section in &raw.sections {
        let name = normalize_name(&section.name);
        let key = (name.clone(), occurrence(&mut sections, name.clone()));
        anchors.push(Anchor {
            start: section.span,
            end: section.span,
            fields: Vec::new(),
            key: Key::Section(key),
        });
        for entry in &section.entries {
            let end = ends.next().copied().unwrap_or(entry.span);
            let keyword = entry_key(&entry.keyword);
            let n = occurrence(&mut entries, (name.clone(), keyword.clone()));
            anchors.push(Anchor {
                start: entry.span,
                end,
                fields: entry.fields.iter().map(|f| f.span).collect(),
                key: Key::Entry((name.clone(), keyword, n)),
            });
        }
    }
    anchors
}

/// How many times `key` was counted before; counts it.
pub(crate) fn occurrence<K: std::hash::Hash + Eq>(counts: &mut HashMap<K, usize>, key: K) -> usize {
    let count = counts.entry(key).or_insert(0);
    *count += 1;
    *count - 1
}

#[cfg(test)]
mod tests {
    use super::*;

    fn comments(text: &str) -> Comments {
        RawEds::parse_with_comments(text).unwrap().1
    }

    fn lines(lines: &[&str]) -> Vec<String> {
        lines.iter().map(|l| (*l).to_string()).collect()
    }

    fn entry<'a>(c: &'a Comments, section: &str, key: &str) -> &'a Attached {
        &c.entries[&(section.to_string(), key.to_string(), 0)]
    }

    #[test]
    fn header_ends_at_the_last_blank_line_before_the_first_section() {
        let c = comments("$ tool\n\n$ notice\n$  \n$ more\n\n$ about File\n[File]\n");
        assert_eq!(c.header, lines(&["$ tool", "", "$ notice", "$", "$ more"]));
        assert_eq!(c.sections[&("file".to_string(), 0)].before, lines(&["$ about File"]));
    }

    #[test]
    fn a_block_followed_by_a_blank_line_is_all_header() {
        let c = comments("$ one\n$ two\n\n[File]\n");
        assert_eq!(c.header, lines(&["$ one", "$ two"]));
        assert!(c.sections.is_empty());
    }

    #[test]
    fn attaches_before_end_of_line_field_and_trailer() {
        let text = "[IO_Info] $ io\n\
                    $ default\n\
                    Default = 0x0001; $ poll\n\
                    PollInfo = $ poll info\n\
                    0x000F, $ combine\n\
                    1,\n\
                    1; $ output\n\
                    \n\
                    $ end\n";
        let c = comments(text);
        assert_eq!(c.sections[&("io_info".to_string(), 0)].end_of_line.as_deref(), Some("$ io"));
        let default = entry(&c, "io_info", "default");
        assert_eq!(default.before, lines(&["$ default"]));
        assert_eq!(default.end_of_line.as_deref(), Some("$ poll"));
        let poll = entry(&c, "io_info", "pollinfo");
        assert_eq!(poll.end_of_line.as_deref(), Some("$ poll info"));
        let fields: Vec<(usize, Vec<String>)> = poll.fields.clone().into_iter().collect();
        assert_eq!(fields, [(0, lines(&["$ combine"])), (2, lines(&["$ output"]))]);
        assert_eq!(c.trailer, lines(&["$ end"]));
    }

    #[test]
    fn repeated_keywords_are_told_apart() {
        let c = comments("[Foo]\n$ a\nX = 1;\n$ b\nX = 2;\n");
        assert_eq!(c.entries[&("foo".to_string(), "x".to_string(), 1)].before, lines(&["$ b"]));
    }

    #[test]
    fn keeps_bytes_above_0x7f_and_drops_trailing_whitespace() {
        let c = comments("[File]\nA = 1; $ \u{92}\u{b0}\u{ff}  \n");
        assert_eq!(entry(&c, "file", "a").end_of_line.as_deref(), Some("$ \u{92}\u{b0}\u{ff}"));
    }
}
