//! Automatic device replacement (ADR): what the scanner keeps of each node with `adr` in its scan
//! list entry, and how a replacement is recognised. The steps run in the engine between scan
//! cycles (`Scanner`'s ADR step, every [`crate::engine::RECONNECT_INTERVAL`]); each is an event
//! ([`crate::events`]). The guide's page (docs/src/plant/scanner.md, "Automatic device
//! replacement") gives the rules with their sources.
//!
//! 1. *Joined*: when a node with ADR is first in I/O, the scanner reads its configuration
//!    consistency value (Identity attribute 9) and, through the [`ConfigTool`] it was given, its
//!    configuration; with its identity that is the node's [`Known`] record.
//! 2. *Lost*: the node leaves I/O (timed out, not present).
//! 3. *At 63* (`config+address` only): a device runs its duplicate MAC ID check at MAC 63. Once it
//!    is on-line the scanner reads its identity; exactly one lost node whose key matches (the
//!    entry's keying, [`key_matches`]) makes it a replacement: DeviceNet object attribute 1 is set
//!    to the lost MAC, then an Identity Reset. A refused Set (a MAC set by switches), no lost node
//!    that matches (a keying mismatch) or several (two identical nodes lost at once: address
//!    recovery is off for them) leaves the device alone, each reported once.
//! 4. The moved device's duplicate MAC ID check at the lost MAC is watched; the scanner's normal
//!    bring-up takes it into I/O.
//! 5. *Configuration*: a node in I/O whose serial number is not the stored one is a replacement
//!    (moved, or put at the MAC by hand): its CCV is read and compared; when it differs and a
//!    configuration is stored, it is downloaded ([`ConfigTool::download`]: the device resets and
//!    comes back with it) and the node is brought up again. Then the replacement is in I/O.

use crate::keying::{mismatches, ElectronicKey};
use crate::model::{Identity, Keying, ScanEntry};
use devicenet::{Instant, MacId};
use harness_common::error::HarnessError;
use master_core::master::Master;
use std::collections::{HashMap, HashSet};

/// Uploads and downloads a node's configuration (the CLI's is `dnet-master configure`'s).
pub trait ConfigTool {
    /// The configuration of the device at `mac` (an explicit connection is open), as text.
    fn upload(&mut self, master: &mut Master<'_, '_>, mac: MacId) -> Result<String, HarnessError>;
    /// Downloads `config` (what [`ConfigTool::upload`] gave) to the device at `mac`, resets it and
    /// waits until it is back on-line.
    fn download(&mut self, master: &mut Master<'_, '_>, mac: MacId, config: &str)
        -> Result<(), HarnessError>;
}

/// What the scanner keeps of a node with ADR, from when it joined.
#[derive(Clone, Debug, Default)]
pub struct Known {
    /// The identity read at its bring-up.
    pub identity: Identity,
    /// Identity attribute 9 (`None`: the device does not have it).
    pub ccv: Option<u16>,
    /// The configuration uploaded ([`ConfigTool::upload`]; `None`: none stored).
    pub config: Option<String>,
}

/// A device seen checking MAC 63.
#[derive(Clone, Copy, Debug)]
pub(crate) struct At63 {
    pub(crate) serial: u32,
    pub(crate) at: Instant,
    /// Dealt with (moved, refused or left alone): not looked at again.
    pub(crate) handled: bool,
}

/// A replacement under way at a lost MAC.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Pending {
    /// The replacement's serial number.
    pub(crate) serial: u32,
    /// When it appeared at MAC 63 (`None`: it came at the MAC itself).
    pub(crate) appeared: Option<Instant>,
    /// Its duplicate MAC ID check at the lost MAC was seen.
    pub(crate) checked: bool,
    /// When it is on-line at the lost MAC (from its check).
    pub(crate) online: Option<Instant>,
    /// When it was moved.
    pub(crate) moved_at: Option<Instant>,
}

/// The ADR state of a scanner. See the [module docs](self).
#[derive(Default)]
pub(crate) struct Adr {
    pub(crate) known: HashMap<u8, Known>,
    pub(crate) lost: HashSet<u8>,
    pub(crate) at63: Option<At63>,
    pub(crate) pending: HashMap<u8, Pending>,
    /// The sets of MACs reported as identical lost nodes.
    pub(crate) disabled: HashSet<Vec<u8>>,
    pub(crate) tool: Option<Box<dyn ConfigTool + Send>>,
    /// When devices ADR waits for come on-line (at most 64).
    pub(crate) wakes: Vec<Instant>,
}

/// The major revision of `revision` ("1.3" → 1).
#[must_use]
pub fn major_of(revision: Option<&str>) -> Option<u8> {
    revision.and_then(|r| r.split('.').next()).and_then(|m| m.parse().ok())
}

/// Whether `device` fits `entry`'s electronic key under the entry's keying
/// ([`crate::keying::mismatches`]), falling back to the identity the node had (`known`) for a
/// vendor ID, device type, product code or major revision the entry does not give: a replacement
/// must be the same kind of device (vendor, device type, product code) whatever the keying.
#[must_use]
pub fn key_matches(entry: &ScanEntry, known: &Identity, device: &Identity) -> bool {
    let given = entry.electronic_key();
    let had = known.electronic_key();
    let key = ElectronicKey {
        vendor_id: given.vendor_id.or(had.vendor_id),
        device_type: given.device_type.or(had.device_type),
        product_code: given.product_code.or(had.product_code),
        major_revision: given.major_revision.or(had.major_revision),
        minor_revision: given.minor_revision,
    };
    let got = device.electronic_key();
    match entry.keying {
        Keying::Disabled => mismatches(Keying::Exact, &key.kind(), &got).is_empty(),
        keying => mismatches(keying, &key, &got).is_empty(),
    }
}

/// The identity key of two lost nodes compared for "identical" (vendor, device type, product
/// code, major revision).
pub(crate) fn identity_key(id: &Identity) -> (Option<u16>, Option<u16>, Option<u16>, Option<u8>) {
    (id.vendor_id, id.device_type, id.product_code, major_of(id.revision.as_deref()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    fn entry(keying: Keying, major: Option<u8>) -> ScanEntry {
        ScanEntry {
            mac: 5,
            connection: "poll".into(),
            ack_suppression: false,
            inhibit_ms: None,
            vendor_id: Some(0x1234),
            device_type: None,
            product_code: Some(1),
            major_revision: major,
            minor_revision: None,
            input_size: 18,
            output_size: 8,
            name: None,
            adr: crate::model::AdrMode::ConfigAddress,
            keying,
            enabled: true,
        }
    }

    fn id(vendor: u16, device_type: u16, product: u16, revision: &str) -> Identity {
        Identity {
            vendor_id: Some(vendor),
            device_type: Some(device_type),
            product_code: Some(product),
            revision: Some(revision.into()),
            ..Identity::default()
        }
    }

    #[test]
    fn keys_minor_from_the_entry_only() {
        let known = id(0x1234, 12, 1, "1.5");
        let mut e = entry(Keying::Compatible, None);
        e.minor_revision = Some(3);
        assert!(key_matches(&e, &known, &id(0x1234, 12, 1, "1.3")));
        assert!(!key_matches(&e, &known, &id(0x1234, 12, 1, "1.2")), "older minor than the entry's");
        e.minor_revision = None;
        assert!(key_matches(&e, &known, &id(0x1234, 12, 1, "1.2")), "the lost node's minor is no key");
    }

    #[rstest]
    #[case::exact_same(Keying::Exact, Some(1), id(0x1234, 12, 1, "1.2"), true)]
    #[case::exact_later_major(Keying::Exact, Some(1), id(0x1234, 12, 1, "2.1"), false)]
    #[case::compatible_later_major(Keying::Compatible, Some(1), id(0x1234, 12, 1, "2.1"), false)]
    #[case::compatible_same_major(Keying::Compatible, Some(1), id(0x1234, 12, 1, "1.7"), true)]
    #[case::compatible_earlier_major(Keying::Compatible, Some(2), id(0x1234, 12, 1, "1.1"), false)]
    #[case::disabled_other_revision(Keying::Disabled, Some(3), id(0x1234, 12, 1, "1.1"), true)]
    #[case::disabled_other_product(Keying::Disabled, None, id(0x1234, 12, 2, "1.1"), false)]
    #[case::device_type_from_the_known_identity(Keying::Exact, None, id(0x1234, 43, 1, "1.1"), false)]
    fn keys(#[case] keying: Keying, #[case] major: Option<u8>, #[case] device: Identity, #[case] fits: bool) {
        let known = id(0x1234, 12, 1, "1.1");
        assert_eq!(key_matches(&entry(keying, major), &known, &device), fits);
    }
}
