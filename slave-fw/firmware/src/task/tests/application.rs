//! The application's object in the converter task (the update object's wiring, src/update.rs).

use super::*;
use devicenet::explicit::Request;
use devicenet::slave::{Reply, ServiceError};
use devicenet::Duration;
use embedded_storage_inmemory::MemFlash;
use fw_image::{Revision, Trailer};
use slave_fw::converter::RESET_DELAY;
use slave_fw::update::{BootState, MarkError, Platform, PAGE_SIZE, UPDATE_CLASS};

/// An object of class 0x6A that answers one byte, asks for a reset [`RESET_DELAY`] after
/// each request, and records what the task hands it.
#[derive(Default)]
struct Fake {
    requests: Vec<(u16, u8, u8)>,
    events: Vec<Event>,
    confirmed: usize,
    reset_at: Option<Instant>,
}

impl ApplicationObject for Fake {
    fn handle(
        &mut self,
        req: &Request<'_>,
        reply: &mut Reply<'_>,
        _io_established: bool,
        now: Instant,
    ) -> Option<Result<(), ServiceError>> {
        (req.class == UPDATE_CLASS).then(|| {
            self.requests.push((req.class, req.instance as u8, req.service.as_raw()));
            self.reset_at = Some(now + RESET_DELAY);
            reply.u8(0x42)
        })
    }
    fn class_revision(&self, class: u16) -> Option<u16> {
        (class == UPDATE_CLASS).then_some(1)
    }
}

impl Application for Fake {
    fn object(&mut self) -> Option<&mut dyn ApplicationObject> {
        Some(self)
    }
    fn on_event(&mut self, event: &Event) {
        self.events.push(*event);
    }
    fn confirmed(&mut self) {
        self.confirmed += 1;
    }
    fn poll_reset(&mut self, now: Instant) -> bool {
        let due = self.reset_at.is_some_and(|at| now >= at);
        if due {
            self.reset_at = None;
        }
        due
    }
    fn poll_at(&self) -> Option<Instant> {
        self.reset_at
    }
}

/// Get_Attribute_Single of class 0x6A instance 1 over the explicit connection (8/8 body).
fn get(attribute: u8) -> Input {
    Input::Frame(frame(0x42C, &[0x00, 0x0E, 0x6A, 0x01, attribute]))
}

#[test]
fn the_object_answers_sees_every_event_and_its_reset_follows_the_response() {
    let mut hw = Recorder::default();
    let (mut task, now) = established_with(&mut hw, Fake::default());
    assert_eq!(task.application().confirmed, 1, "on-line and not on trial: confirmed once");
    let seen = task.application().events.len();
    task.take_inputs(get(5), || None, now, &mut hw);
    assert_eq!(hw.frames, [frame(0x42B, &[0x00, 0x8E, 0x42])]);
    assert_eq!(task.application().requests, [(0x6A, 1, 0x0E)]);

    // The reset: due RESET_DELAY after the request, carried out once, after the response.
    let due = now + RESET_DELAY;
    assert_eq!(task.poll_at().map(|at| at <= due), Some(true));
    task.handle_timeout(now + Duration::from_millis(99), &mut hw);
    assert!(hw.resets.is_empty());
    task.handle_timeout(due, &mut hw);
    assert_eq!(hw.resets, [(1, ResetKind::PowerCycle)]);
    task.handle_timeout(due + RESET_DELAY, &mut hw);
    assert_eq!(hw.resets.len(), 1);

    // The explicit connection released through the Group 2 Only port: the object sees the
    // event, as the hardware does.
    hw.events.clear();
    task.take_inputs(Input::Frame(frame(0x42E, &[0x00, 0x4C, 0x03, 0x01, 0x01])), || None, due, &mut hw);
    assert_eq!(hw.frames.last(), Some(&frame(0x42B, &[0x00, 0xCC])));
    assert!(!hw.events.is_empty());
    assert_eq!(task.application().events[seen..], hw.events[..]);
}

#[test]
fn an_image_still_on_trial_when_on_line_is_not_confirmed() {
    let mut hw = Recorder { on_trial: true, ..Recorder::default() };
    let (task, _) = established_with(&mut hw, Fake::default());
    assert!(hw.events.is_empty(), "established clears them");
    assert_eq!(task.application().confirmed, 0);
}

#[test]
fn without_an_object_class_0x6a_does_not_exist() {
    let mut hw = Recorder::default();
    let (mut task, now) = established(&mut hw);
    task.take_inputs(get(5), || None, now, &mut hw);
    assert_eq!(hw.frames, [frame(0x42B, &[0x00, 0x94, 0x16, 0xFF])]);
    let mut hw = Recorder::default();
    let (mut task, now) = established_with(&mut hw, None::<Fake>);
    task.take_inputs(get(5), || None, now, &mut hw);
    assert_eq!(hw.frames, [frame(0x42B, &[0x00, 0x94, 0x16, 0xFF])]);
}

type Flash = MemFlash<{ 2 * PAGE_SIZE }, PAGE_SIZE, 4>;

/// Apply always fails (never reached here).
struct NoMark;

impl MarkUpdated for NoMark {
    fn mark_updated(&mut self, _: &Trailer) -> Result<(), MarkError> {
        Err(MarkError)
    }
}

/// The real update object in the task, started as `boot`: attributes 1 (state), 5, 6, 7.
fn update_object_attributes(boot: BootState, on_trial: bool) -> Vec<Vec<u8>> {
    let mut flash = Box::new(Flash::new(0xFF));
    let platform = Platform {
        board_id: 4,
        running: Revision { major: 1, minor: 2 },
        public_key: [7; 32],
        bootloader: Revision { major: 0, minor: 1 },
        boot,
    };
    let object = UpdateObject::new(&mut *flash, NoMark, platform).unwrap();
    let mut hw = Recorder { on_trial, ..Recorder::default() };
    let (mut task, now) = established_with(&mut hw, Some(object));
    for attribute in [1, 5, 6, 7] {
        task.take_inputs(get(attribute), || None, now, &mut hw);
    }
    hw.frames.iter().map(|f| f.data().to_vec()).collect()
}

#[test]
fn the_update_object_answers_through_the_task_and_a_trial_ends_on_line() {
    let confirmed = update_object_attributes(BootState::Trial, false);
    let want = |state: u8| {
        vec![
            vec![0x00, 0x8E, state],
            vec![0x00, 0x8E, 0x80, 0x00],
            vec![0x00, 0x8E, 0x80, 0xFF, 0x01, 0x00],
            vec![0x00, 0x8E, 0x04, 0x00],
        ]
    };
    assert_eq!(confirmed, want(0), "on-line, confirmed: idle");
    assert_eq!(update_object_attributes(BootState::Trial, true), want(5), "still on trial");
    assert_eq!(update_object_attributes(BootState::RolledBack, false), want(6));
}
