//! The console's health requests ([`crate::health`]):
//!
//! | request | answer |
//! |---|---|
//! | `GET /api/health` | the [`HealthReport`] as JSON |
//! | `GET /api/health.csv` | its node table as CSV ([`HealthReport::csv`]) |
//! | `POST /api/health/clear` | clears every statistic, then the fresh report as JSON |
//!
//! The report comes from the scanner's loop (a [`ConsoleCommand::Health`], answered between
//! cycles, within [`COMMAND_TIMEOUT`]).

use super::http::Response;
use super::COMMAND_TIMEOUT;
use crate::health::HealthReport;
use crate::model::{ConsoleCommand, Shared};
use serde_json::json;
use std::sync::mpsc;

/// Why the scanner gave no report.
#[derive(Debug, thiserror::Error)]
enum HealthApiError {
    /// The command could not be sent.
    #[error("the scanner is not running")]
    NotRunning,
    /// No answer in time.
    #[error("no answer from the scanner within {} s", COMMAND_TIMEOUT.as_secs())]
    Timeout,
    /// The scanner stopped before answering.
    #[error("the scanner stopped before answering")]
    Stopped,
}

impl HealthApiError {
    fn status(&self) -> u16 {
        match self {
            HealthApiError::Timeout => 504,
            HealthApiError::NotRunning | HealthApiError::Stopped => 503,
        }
    }
}

/// Asks the scanner's loop for its health report (after clearing it when `clear`).
fn ask(shared: &Shared, clear: bool) -> Result<HealthReport, HealthApiError> {
    let (tx, rx) = mpsc::channel();
    shared
        .commands
        .lock()
        .map_err(|_| HealthApiError::NotRunning)?
        .send(ConsoleCommand::Health { clear, reply: tx })
        .map_err(|_| HealthApiError::NotRunning)?;
    rx.recv_timeout(COMMAND_TIMEOUT).map_err(|e| match e {
        mpsc::RecvTimeoutError::Timeout => HealthApiError::Timeout,
        mpsc::RecvTimeoutError::Disconnected => HealthApiError::Stopped,
    })
}

fn failed(e: &HealthApiError) -> Response {
    let body = json!({"ok": false, "error": e.to_string()}).to_string();
    Response::new(e.status(), "application/json", body.into_bytes())
}

/// `GET /api/health` (`clear` false) and `POST /api/health/clear` (`clear` true).
pub(super) fn report(shared: &Shared, clear: bool) -> Response {
    match ask(shared, clear) {
        Ok(r) => {
            let mut v = serde_json::to_value(&r).unwrap_or_default();
            v["ok"] = json!(true);
            Response::new(200, "application/json", v.to_string().into_bytes())
        }
        Err(e) => failed(&e),
    }
}

/// `GET /api/health.csv`.
pub(super) fn csv(shared: &Shared) -> Response {
    match ask(shared, false) {
        Ok(r) => Response::new(200, "text/csv; charset=utf-8", r.csv().into_bytes()),
        Err(e) => failed(&e),
    }
}
