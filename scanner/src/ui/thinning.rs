//! What the web console's history keeps of the scanner's samples: every change of a node's input
//! image, and one sample a second while it stays the same ([`SAMPLE_EVERY_MS`]).

use crate::model::Sample;
use std::collections::HashMap;

/// A sample is stored when the input changed, or this long after the node's last stored one.
pub const SAMPLE_EVERY_MS: i64 = 1000;

/// Keeps the samples worth storing: a changed input, or [`SAMPLE_EVERY_MS`] since the last one.
#[derive(Default)]
pub struct Thinning {
    last: HashMap<u8, (i64, Vec<u8>)>,
}

impl Thinning {
    /// The samples of `samples` worth storing.
    pub fn keep(&mut self, samples: Vec<Sample>) -> Vec<Sample> {
        samples
            .into_iter()
            .filter(|s| {
                let keep = match self.last.get(&s.mac) {
                    Some((at, input)) => *input != s.input || s.unix_ms - at >= SAMPLE_EVERY_MS,
                    None => true,
                };
                if keep {
                    self.last.insert(s.mac, (s.unix_ms, s.input.clone()));
                }
                keep
            })
            .collect()
    }
}
