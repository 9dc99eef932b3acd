//! The console's event log and scan-list changes ([`crate::events`], [`ListEdit`]):
//!
//! | request | answer |
//! |---|---|
//! | `GET /api/events?since=N` | the events after sequence number N (all kept without), oldest first |
//! | `POST /api/scanlist/add` | a new entry: the scan list file's keys as JSON (`{"mac": 9, "input_size": 18, "output_size": 8, "keying": "compatible", "adr": "config+address"}`) |
//! | `POST /api/scanlist/edit` | the entry at its MAC replaced (same JSON) |
//! | `POST /api/scanlist/remove` | `{"mac": 9}` |
//! | `POST /api/scanlist/enable` | `{"mac": 9, "enabled": false}`: disabled for maintenance, kept |
//!
//! The changes need the engineer's role (`auth`: a state-changing request other than outputs and
//! breaker commands). Both come from the scanner's loop, answered between cycles within
//! [`COMMAND_TIMEOUT`]; a refused change is `400` with the reason (the key, the MAC).

use super::http::Response;
use super::COMMAND_TIMEOUT;
use crate::events::ScanEvent;
use crate::model::{ConsoleCommand, ListEdit, Reply, ScanEntry, Shared};
use serde_json::{json, Value};
use std::sync::mpsc;

/// Why a request got no answer or was refused.
#[derive(Debug, thiserror::Error)]
enum ListApiError {
    /// The command could not be sent.
    #[error("the scanner is not running")]
    NotRunning,
    /// No answer in time.
    #[error("no answer from the scanner within {} s", COMMAND_TIMEOUT.as_secs())]
    Timeout,
    /// The scanner stopped before answering.
    #[error("the scanner stopped before answering")]
    Stopped,
    /// The request's body is not what the action takes.
    #[error("{0}")]
    BadRequest(String),
    /// The scanner refused the change.
    #[error("{0}")]
    Refused(String),
    /// No such action.
    #[error("no such scan-list action '{0}': add, edit, remove or enable")]
    NoAction(String),
}

impl ListApiError {
    fn status(&self) -> u16 {
        match self {
            ListApiError::Timeout => 504,
            ListApiError::NotRunning | ListApiError::Stopped => 503,
            ListApiError::BadRequest(_) | ListApiError::Refused(_) => 400,
            ListApiError::NoAction(_) => 404,
        }
    }
}

fn ask<T>(shared: &Shared, cmd: ConsoleCommand, rx: &mpsc::Receiver<T>) -> Result<T, ListApiError> {
    shared
        .commands
        .lock()
        .map_err(|_| ListApiError::NotRunning)?
        .send(cmd)
        .map_err(|_| ListApiError::NotRunning)?;
    rx.recv_timeout(COMMAND_TIMEOUT).map_err(|e| match e {
        mpsc::RecvTimeoutError::Timeout => ListApiError::Timeout,
        mpsc::RecvTimeoutError::Disconnected => ListApiError::Stopped,
    })
}

fn answer(r: Result<Value, ListApiError>) -> Response {
    let (status, body) = match r {
        Ok(v) => (200, v),
        Err(e) => (e.status(), json!({"ok": false, "error": e.to_string()})),
    };
    Response::new(status, "application/json", body.to_string().into_bytes())
}

/// `GET /api/events?since=N`.
pub(super) fn events(shared: &Shared, since: Option<u64>) -> Response {
    let (tx, rx) = mpsc::channel::<Vec<ScanEvent>>();
    let r = ask(shared, ConsoleCommand::Events { since: since.unwrap_or(0), reply: tx }, &rx)
        .map(|events| json!({"ok": true, "events": events}));
    answer(r)
}

/// `POST /api/scanlist/ACTION` with `body`.
pub(super) fn edit(shared: &Shared, action: &str, body: &[u8]) -> Response {
    answer(parse(action, body).and_then(|edit| {
        let (tx, rx) = mpsc::channel::<Reply>();
        ask(shared, ConsoleCommand::EditList { edit, reply: tx }, &rx)?
            .map(|_| json!({"ok": true}))
            .map_err(ListApiError::Refused)
    }))
}

fn parse(action: &str, body: &[u8]) -> Result<ListEdit, ListApiError> {
    let bad = |e: serde_json::Error| ListApiError::BadRequest(format!("the {action} request's body: {e}"));
    let mac_of = |v: &Value| -> Result<u8, ListApiError> {
        v.get("mac")
            .and_then(Value::as_u64)
            .and_then(|m| u8::try_from(m).ok())
            .filter(|m| *m <= 63)
            .ok_or_else(|| {
                ListApiError::BadRequest(format!("{action}: \"mac\" 0..=63 is missing or out of range"))
            })
    };
    match action {
        "add" => Ok(ListEdit::Add(serde_json::from_slice::<ScanEntry>(body).map_err(bad)?)),
        "edit" => Ok(ListEdit::Edit(serde_json::from_slice::<ScanEntry>(body).map_err(bad)?)),
        "remove" => Ok(ListEdit::Remove(mac_of(&serde_json::from_slice(body).map_err(bad)?)?)),
        "enable" => {
            let v: Value = serde_json::from_slice(body).map_err(bad)?;
            let enabled = v.get("enabled").and_then(Value::as_bool).ok_or_else(|| {
                ListApiError::BadRequest("enable: \"enabled\": true or false is missing".into())
            })?;
            Ok(ListEdit::Enable { mac: mac_of(&v)?, enabled })
        }
        other => Err(ListApiError::NoAction(other.to_string())),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    #[rstest]
    #[case::enable(
        "enable",
        r#"{"mac": 9, "enabled": false}"#,
        Ok(ListEdit::Enable { mac: 9, enabled: false })
    )]
    #[case::remove("remove", r#"{"mac": 63}"#, Ok(ListEdit::Remove(63)))]
    #[case::mac_out_of_range("remove", r#"{"mac": 64}"#, Err("\"mac\" 0..=63"))]
    #[case::enabled_missing("enable", r#"{"mac": 9}"#, Err("\"enabled\""))]
    #[case::unknown_key(
        "add",
        r#"{"mac": 9, "input_size": 1, "output_size": 1, "colour": 1}"#,
        Err("unknown field `colour`")
    )]
    #[case::no_such_action("rename", "{}", Err("no such scan-list action 'rename'"))]
    fn requests(#[case] action: &str, #[case] body: &str, #[case] want: Result<ListEdit, &str>) {
        match (parse(action, body.as_bytes()), want) {
            (Ok(got), Ok(w)) => assert_eq!(got, w),
            (Err(e), Err(w)) => assert!(e.to_string().contains(w), "{e}"),
            (got, w) => panic!("{got:?}, expected {w:?}"),
        }
    }

    #[test]
    fn an_entry_takes_keying_and_adr() {
        let body = r#"{"mac": 9, "input_size": 18, "output_size": 8, "keying": "compatible", "adr": "config+address"}"#;
        let Ok(ListEdit::Add(e)) = parse("add", body.as_bytes()) else { panic!("not an add") };
        assert_eq!(
            (e.keying, e.adr, e.enabled),
            (crate::model::Keying::Compatible, crate::model::AdrMode::ConfigAddress, true)
        );
    }
}
