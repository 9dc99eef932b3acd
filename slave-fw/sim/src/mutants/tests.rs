use super::*;
use proptest::prelude::*;

fn mac(n: u8) -> MacId {
    MacId::new(n).unwrap()
}

#[test]
fn names_are_unique_and_parse_refuses_unknown_ones_with_the_list() {
    for (k, m) in MUTANTS.iter().enumerate() {
        assert!(MUTANTS[k + 1..].iter().all(|o| o.id != m.id && o.kind != m.kind), "{}", m.id);
        assert_eq!(parse(m.id), Ok(m));
    }
    let e = parse("nonsense").unwrap_err();
    assert!(e.contains("answers-ucmm") && e.contains("slow-explicit-responses"), "{e}");
}

#[test]
fn held_frames_go_out_when_due_and_the_others_in_order() {
    let node = SoftSlave::reference(mac(5));
    let mut hook = find("slow-poll-responses").unwrap().hook();
    let poll = CanFrame::from_raw(0x3C5, &[0; 8]).unwrap();
    let other = CanFrame::from_raw(0x42B, &[0x00, 0x8E, 0x34, 0x12]).unwrap();
    hook.transmit(poll, Instant::from_millis(10), node.node());
    hook.transmit(other, Instant::from_millis(10), node.node());
    assert_eq!(hook.poll_transmit(Instant::from_millis(10)), Some(other));
    assert_eq!(hook.poll_transmit(Instant::from_millis(10)), None);
    assert_eq!(hook.poll_at(), Some(Instant::from_millis(160)));
    assert_eq!(hook.poll_transmit(Instant::from_millis(160)), Some(poll));
    assert_eq!(hook.poll_at(), None);
}

proptest! {
    /// Any frames, any mutant: no panic, and the node keeps its own identifiers and the
    /// Group 3 UCMM response (protocol §8).
    #[test]
    fn any_frames_to_any_mutant(
        k in 0..MUTANTS.len(),
        frames in proptest::collection::vec((0u16..0x800, proptest::collection::vec(any::<u8>(), 0..=8), 0u64..3000), 0..60),
    ) {
        let mut device = MUTANTS[k].device(mac(5));
        let mut now = Instant::ZERO;
        device.power_on(now);
        for (id, data, step) in frames {
            now += Duration::from_millis(step);
            while device.poll_at().is_some_and(|at| at <= now) {
                let at = device.poll_at().unwrap();
                device.handle_timeout(at);
                while device.poll_transmit().is_some() {}
            }
            if let Ok(f) = CanFrame::from_raw(id, &data) {
                device.handle_frame(&f, now);
            }
            while let Some(f) = device.poll_transmit() {
                let id = f.id().as_raw();
                prop_assert!(id >= 0x400 || id & 0x3F == 5, "{f:?}");
            }
        }
    }
}
