//! `GET /api/project/compare`: the network project given with `dnet-master ui --project FILE`
//! against the running network ([`crate::project::console`]).
//!
//! The answer is `{"ok", "project", "compared", "not_compared", "differences", "equal"}`:
//! `compared` counts what was compared (`nodes`, `scan_list`, `identity`, `configuration`,
//! `parameters`), `not_compared` lists each part left out with why (`wanted: false` when the
//! project itself asks for no comparison, as keying `disabled`), `differences` each
//! `{mac, what, expected, found}`. `equal` is true only when something was compared, nothing
//! differs and nothing the project asked for was left out. When nothing at all could be compared
//! (and no difference found) the answer is `409` with `ok: false` and the reason, never "no differences"; without
//! `--project` it is `404`; before the scanner has its scan list `503`. Reading is all it does: a viewer may ask.
//!
//! The attributes the node states do not hold (the CCV, the parameters) are read by the
//! scanner's loop between its cycles ([`ConsoleCommand::Get`]), each within [`COMMAND_TIMEOUT`].

use super::http::Response;
use super::COMMAND_TIMEOUT;
use crate::model::{ConsoleCommand, Shared};
use crate::project::console::compare_running;
use crate::project::Project;
use serde_json::json;
use std::sync::mpsc;

/// Reads one attribute through the scanner's loop; why not in words.
fn read(shared: &Shared, mac: u8, class: u16, instance: u16, attribute: u8) -> Result<Vec<u8>, String> {
    let (reply, rx) = mpsc::channel();
    shared
        .commands
        .lock()
        .map_err(|_| "the scanner is not taking commands".to_string())?
        .send(ConsoleCommand::Get { mac, class, instance, attribute, reply })
        .map_err(|_| "the scanner is not running".to_string())?;
    match rx.recv_timeout(COMMAND_TIMEOUT) {
        Ok(answer) => answer,
        Err(mpsc::RecvTimeoutError::Timeout) => {
            Err(format!("no answer from the scanner within {} s", COMMAND_TIMEOUT.as_secs()))
        }
        Err(mpsc::RecvTimeoutError::Disconnected) => Err("the scanner stopped before answering".into()),
    }
}

fn answer(status: u16, value: &serde_json::Value) -> Response {
    Response::new(status, "application/json", value.to_string().into_bytes())
}

/// `GET /api/project/compare` (module docs); `project` is the file given, `name` its path.
pub(super) fn compare(shared: &Shared, project: Option<&(String, Project)>) -> Response {
    let Some((name, project)) = project else {
        return answer(
            404,
            &json!({
                "ok": false,
                "project": null,
                "error": "no project: start the console with `dnet-master ui --project FILE`"
            }),
        );
    };
    let nodes = match shared.state.lock() {
        Ok(s) => s.nodes.clone(),
        Err(_) => return answer(500, &json!({"ok": false, "error": "the scanner's state is unavailable"})),
    };
    if nodes.is_empty() {
        let error =
            "the scanner has no scan list yet (it is still bringing the network up): nothing compared";
        return answer(503, &json!({"ok": false, "project": name, "error": error}));
    }
    let c = compare_running(project, &nodes, &mut |mac, class, instance, attribute| {
        read(shared, mac, class, instance, attribute)
    });
    let mut v = json!({
        "ok": true,
        "project": name,
        "compared": c.compared,
        "not_compared": c.not_compared,
        "differences": c.differences,
        "equal": c.equal(),
    });
    if !c.anything_compared() && c.differences.is_empty() {
        v["ok"] = json!(false);
        v["error"] = json!(format!(
            "nothing could be compared: {} of the project's {} node(s) in the scan list, no part of them read",
            c.compared.nodes,
            project.node.len()
        ));
        return answer(409, &v);
    }
    answer(200, &v)
}
