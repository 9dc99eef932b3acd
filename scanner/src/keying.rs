//! Electronic keying: whether a device's identity fits a key (a scan-list entry, a project node),
//! one rule for the scanner's bring-up, automatic device replacement and project comparison.
//!
//! The key is Identity attributes 1–4 (vendor ID, device type, product code, revision
//! `major.minor`). [`mismatches`] compares each part the key gives:
//!
//! | keying | vendor ID, device type, product code, major revision | minor revision |
//! |---|---|---|
//! | `exact` | equal | equal |
//! | `compatible` | equal | the device's equal to the key's or later |
//! | `disabled` | not compared | not compared |
//!
//! `compatible` is the CIP electronic key's compatibility bit: a device with the bit set in the
//! key accepts it when the major revision is its own and the minor revision at most its own
//! (OpENer, `CheckElectronicKeyData` in `source/src/cip/cipelectronickey.c`: "Major must match,
//! Minor != 0 and <= MinorRevision"); Rockwell's "compatible module" keying says the same
//! (1756-6.5.3: "these characteristics must match: module type, catalog number, major revision.
//! The minor revision must be equal to or greater than the one specified"). Guide: plant/scanner.md,
//! "Electronic keying".

use serde::{Deserialize, Serialize};
use std::fmt;

/// How an electronic key is compared with the device.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Keying {
    /// Every part the key gives equal.
    #[default]
    Exact,
    /// Vendor ID, device type, product code and major revision equal; the device's minor
    /// revision the key's or later (the CIP compatibility bit).
    Compatible,
    /// Not compared.
    Disabled,
}

impl Keying {
    /// `true` for [`Keying::Exact`].
    #[must_use]
    pub fn is_exact(&self) -> bool {
        *self == Keying::Exact
    }

    /// The name in the scan list and project files.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Keying::Exact => "exact",
            Keying::Compatible => "compatible",
            Keying::Disabled => "disabled",
        }
    }
}

/// An electronic key, or what a device answered for one: each part `None` when not given (a key)
/// or not read (a device).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct ElectronicKey {
    /// Identity attribute 1.
    pub vendor_id: Option<u16>,
    /// Identity attribute 2.
    pub device_type: Option<u16>,
    /// Identity attribute 3.
    pub product_code: Option<u16>,
    /// Identity attribute 4, first byte.
    pub major_revision: Option<u8>,
    /// Identity attribute 4, second byte.
    pub minor_revision: Option<u8>,
}

impl ElectronicKey {
    /// The key with its revision from the text `major.minor` (as the scanner keeps Identity
    /// attribute 4); a part that is no number stays `None`.
    #[must_use]
    pub fn with_revision_text(self, revision: Option<&str>) -> Self {
        let mut parts = revision.unwrap_or("").split('.');
        let mut next = || parts.next().and_then(|p| p.parse::<u8>().ok());
        let major_revision = next();
        let minor_revision = next();
        ElectronicKey { major_revision, minor_revision, ..self }
    }

    /// Only the kind of device: vendor ID, device type and product code (no revision).
    #[must_use]
    pub fn kind(self) -> Self {
        ElectronicKey { major_revision: None, minor_revision: None, ..self }
    }

    fn part(&self, part: KeyPart) -> Option<u16> {
        match part {
            KeyPart::VendorId => self.vendor_id,
            KeyPart::DeviceType => self.device_type,
            KeyPart::ProductCode => self.product_code,
            KeyPart::MajorRevision => self.major_revision.map(u16::from),
            KeyPart::MinorRevision => self.minor_revision.map(u16::from),
        }
    }
}

/// A part of the electronic key.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum KeyPart {
    /// Identity attribute 1.
    VendorId,
    /// Identity attribute 2.
    DeviceType,
    /// Identity attribute 3.
    ProductCode,
    /// Identity attribute 4, major.
    MajorRevision,
    /// Identity attribute 4, minor.
    MinorRevision,
}

impl KeyPart {
    /// Every part, in the key's order.
    pub const ALL: [KeyPart; 5] = [
        KeyPart::VendorId,
        KeyPart::DeviceType,
        KeyPart::ProductCode,
        KeyPart::MajorRevision,
        KeyPart::MinorRevision,
    ];

    /// The part in words ("vendor ID").
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            KeyPart::VendorId => "vendor ID",
            KeyPart::DeviceType => "device type",
            KeyPart::ProductCode => "product code",
            KeyPart::MajorRevision => "major revision",
            KeyPart::MinorRevision => "minor revision",
        }
    }

    /// The part's key in the scan list and project files (`vendor_id`).
    #[must_use]
    pub fn key(self) -> &'static str {
        match self {
            KeyPart::VendorId => "vendor_id",
            KeyPart::DeviceType => "device_type",
            KeyPart::ProductCode => "product_code",
            KeyPart::MajorRevision => "major_revision",
            KeyPart::MinorRevision => "minor_revision",
        }
    }

    /// `true` for the parts shown in hexadecimal (vendor ID, device type).
    fn hexadecimal(self) -> bool {
        matches!(self, KeyPart::VendorId | KeyPart::DeviceType)
    }
}

/// A part of the key the device does not fit.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct KeyMismatch {
    /// The part.
    pub part: KeyPart,
    /// The keying it was compared under.
    pub keying: Keying,
    /// The key's value.
    pub expected: u16,
    /// The device's (`None`: not read).
    pub read: Option<u16>,
}

impl KeyMismatch {
    /// `true` when the device's value may be the key's or later (compatible keying, minor
    /// revision).
    #[must_use]
    pub fn or_later(&self) -> bool {
        self.keying == Keying::Compatible && self.part == KeyPart::MinorRevision
    }

    fn show(&self, v: Option<u16>) -> String {
        match (v, self.part.hexadecimal()) {
            (Some(v), true) => format!("0x{v:04X}"),
            (Some(v), false) => v.to_string(),
            (None, _) => "nothing".into(),
        }
    }
}

impl fmt::Display for KeyMismatch {
    /// `expected vendor ID 0x1234, read 0x1235`; `expected minor revision 3 or later, read 2`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let later = if self.or_later() { " or later" } else { "" };
        write!(
            f,
            "expected {} {}{later}, read {}",
            self.part.name(),
            self.show(Some(self.expected)),
            self.show(self.read)
        )
    }
}

/// The parts of `key` that `device` does not fit under `keying` (empty: it fits). A part the key
/// does not give is not compared; a part the key gives and the device did not answer is a
/// mismatch.
#[must_use]
pub fn mismatches(keying: Keying, key: &ElectronicKey, device: &ElectronicKey) -> Vec<KeyMismatch> {
    if keying == Keying::Disabled {
        return Vec::new();
    }
    KeyPart::ALL
        .into_iter()
        .filter_map(|part| {
            let expected = key.part(part)?;
            let read = device.part(part);
            let fits = match (keying, part) {
                (Keying::Compatible, KeyPart::MinorRevision) => read.is_some_and(|r| r >= expected),
                _ => read == Some(expected),
            };
            (!fits).then_some(KeyMismatch { part, keying, expected, read })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    fn key(revision: &str) -> ElectronicKey {
        ElectronicKey {
            vendor_id: Some(0x1234),
            device_type: Some(0x0C),
            product_code: Some(1),
            ..Default::default()
        }
        .with_revision_text(Some(revision))
    }

    fn texts(keying: Keying, want: &str, device: &str) -> Vec<String> {
        mismatches(keying, &key(want), &key(device)).iter().map(ToString::to_string).collect()
    }

    #[rstest]
    #[case::exact_equal(Keying::Exact, "2.3", "2.3", &[])]
    #[case::exact_newer_minor(Keying::Exact, "2.3", "2.4", &["expected minor revision 3, read 4"])]
    #[case::exact_older_minor(Keying::Exact, "2.3", "2.2", &["expected minor revision 3, read 2"])]
    #[case::exact_other_major(Keying::Exact, "2.3", "3.3", &["expected major revision 2, read 3"])]
    #[case::compatible_equal(Keying::Compatible, "2.3", "2.3", &[])]
    #[case::compatible_newer_minor(Keying::Compatible, "2.3", "2.9", &[])]
    #[case::compatible_older_minor(Keying::Compatible, "2.3", "2.2", &["expected minor revision 3 or later, read 2"])]
    #[case::compatible_later_major(Keying::Compatible, "2.3", "3.3", &["expected major revision 2, read 3"])]
    #[case::compatible_earlier_major(Keying::Compatible, "2.3", "1.9", &["expected major revision 2, read 1"])]
    #[case::disabled_other_major(Keying::Disabled, "2.3", "3.1", &[])]
    fn the_revision_rule(
        #[case] keying: Keying,
        #[case] want: &str,
        #[case] device: &str,
        #[case] expected: &[&str],
    ) {
        assert_eq!(texts(keying, want, device), expected);
    }

    #[test]
    fn the_kind_is_compared_under_every_keying_but_disabled() {
        let other = ElectronicKey {
            vendor_id: Some(0x1235),
            device_type: Some(0x2B),
            product_code: Some(7),
            ..key("2.3")
        };
        for keying in [Keying::Exact, Keying::Compatible] {
            let got: Vec<String> =
                mismatches(keying, &key("2.3"), &other).iter().map(ToString::to_string).collect();
            assert_eq!(
                got,
                [
                    "expected vendor ID 0x1234, read 0x1235",
                    "expected device type 0x000C, read 0x002B",
                    "expected product code 1, read 7"
                ]
            );
        }
        assert!(mismatches(Keying::Disabled, &key("2.3"), &other).is_empty());
    }

    #[test]
    fn a_part_not_given_is_not_compared_and_a_part_not_read_does_not_fit() {
        let major_only = ElectronicKey { minor_revision: None, ..key("2.3") };
        assert!(mismatches(Keying::Exact, &major_only, &key("2.7")).is_empty());
        let unread = ElectronicKey::default();
        let got = mismatches(Keying::Compatible, &key("2.3"), &unread);
        assert_eq!(got.len(), 5);
        assert_eq!(got[4].to_string(), "expected minor revision 3 or later, read nothing");
    }

    #[test]
    fn the_revision_text_is_major_dot_minor() {
        let k = ElectronicKey::default().with_revision_text(Some("4.12"));
        assert_eq!((k.major_revision, k.minor_revision), (Some(4), Some(12)));
        let k = ElectronicKey::default().with_revision_text(Some("x"));
        assert_eq!((k.major_revision, k.minor_revision), (None, None));
        assert_eq!(ElectronicKey::default().with_revision_text(None), ElectronicKey::default());
    }

    #[test]
    fn the_names_are_the_files() {
        for k in [Keying::Exact, Keying::Compatible, Keying::Disabled] {
            let json = serde_json::to_string(&k).unwrap();
            assert_eq!(json, format!("\"{}\"", k.name()));
            assert_eq!(serde_json::from_str::<Keying>(&json).unwrap(), k);
        }
    }
}
