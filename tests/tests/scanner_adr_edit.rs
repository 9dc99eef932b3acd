//! Scan-list changes while the scanner runs (issue 28 item 5), on the simulated bus: a node
//! disabled for maintenance (released, not scanned, kept) and enabled again, an entry added,
//! edited (keying) and removed; each change an event; refused changes name the reason.

#[path = "support/scan_edit.rs"]
mod scan_edit;

use devicenet::Duration;
use dnet_scanner::events::EventKind;
use dnet_scanner::model::{Keying, ListEdit, NodeStatus};
use dnet_scanner::Scanner;
use scan_edit::{run_for, with_5_and_6_scanned};

fn status(s: &Scanner, mac: u8) -> (NodeStatus, u64) {
    let n = s.state().nodes.iter().find(|n| n.mac == mac).unwrap_or_else(|| panic!("no MAC {mac}"));
    (n.status, n.exchanges)
}

#[test]
fn nodes_are_disabled_enabled_added_edited_and_removed_while_running() {
    with_5_and_6_scanned(|s, m, seven| {
        assert_eq!(status(s, 5).0, NodeStatus::Ok);

        // Disabled: released, not scanned, kept in the list with code 0.
        s.edit(m, ListEdit::Enable { mac: 5, enabled: false }).unwrap();
        run_for(s, m, Duration::from_millis(100));
        let (st, before) = status(s, 5);
        run_for(s, m, Duration::from_secs(2));
        assert_eq!(status(s, 5), (NodeStatus::Disabled, before), "not scanned while disabled");
        assert_eq!(st, NodeStatus::Disabled);
        assert!(!s.scan_list().nodes.iter().find(|n| n.mac == 5).unwrap().enabled);
        assert_eq!(status(s, 6).0, NodeStatus::Ok, "the others go on");

        // Enabled again: back in I/O.
        s.edit(m, ListEdit::Enable { mac: 5, enabled: true }).unwrap();
        run_for(s, m, Duration::from_secs(2));
        let (st, after) = status(s, 5);
        assert_eq!(st, NodeStatus::Ok);
        assert!(after > before);

        // Added, then keyed to another major revision: exact refuses it, compatible too (the major
        // revision must be equal, scanner/src/keying.rs), disabled keying takes it.
        s.edit(m, ListEdit::Add(seven.clone())).unwrap();
        run_for(s, m, Duration::from_secs(2));
        assert_eq!(status(s, 7).0, NodeStatus::Ok);
        let mut later = seven.clone();
        later.major_revision = Some(2);
        later.keying = Keying::Compatible;
        s.edit(m, ListEdit::Edit(later.clone())).unwrap();
        run_for(s, m, Duration::from_secs(2));
        assert_eq!(status(s, 7).0, NodeStatus::KeyingMismatch);
        later.keying = Keying::Disabled;
        s.edit(m, ListEdit::Edit(later)).unwrap();
        run_for(s, m, Duration::from_secs(2));
        assert_eq!(status(s, 7).0, NodeStatus::Ok, "{:?}", s.state().nodes.iter().find(|n| n.mac == 7));

        // Refusals name the reason.
        let e = s.edit(m, ListEdit::Add(seven.clone())).unwrap_err();
        assert!(e.to_string().contains("MAC 7 is in the scan list already"), "{e}");
        let mut zero = seven.clone();
        zero.mac = 0;
        let e = s.edit(m, ListEdit::Add(zero)).unwrap_err();
        assert!(e.to_string().contains("scanner's own"), "{e}");
        let e = s.edit(m, ListEdit::Remove(9)).unwrap_err();
        assert!(e.to_string().contains("MAC 9 is not in the scan list"), "{e}");

        // Removed: released and gone.
        s.edit(m, ListEdit::Remove(7)).unwrap();
        run_for(s, m, Duration::from_millis(200));
        assert!(s.state().nodes.iter().all(|n| n.mac != 7));
        let changes = s.events().of(EventKind::ListChanged).len();
        assert_eq!(changes, 6, "{:#?}", s.events().all());
        s.stop(m).unwrap();
    });
}
