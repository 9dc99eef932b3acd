//! Who is asking, and may they: the console's logins, sessions, role checks and audit records.
//!
//! With a users file (`dnet-master ui --users FILE`, [`crate::accounts`]) every request but the
//! page itself, `GET /api/session` and `POST /api/login` needs a session: `POST /api/login`
//! `{"user", "password"}` checks the password (argon2) and sets the cookie
//! [`COOKIE`]`=ID; HttpOnly; SameSite=Strict; Path=/` (plus `Secure` over TLS). Each session has
//! its own CSRF token (in the login answer and `GET /api/session`); a state-changing request
//! carries it in `X-CSRF-Token`. A session ends with `POST /api/logout`, after [`SESSION_IDLE`]
//! without a request, or when [`MAX_SESSIONS`] newer ones push it out (the least recently used
//! goes first). No session: `401`; a role that may not: `403`; both with the reason in JSON.
//!
//! Without a users file (loopback only, see `dnet-master ui`) every caller is the anonymous `-`
//! with every right, and the token is the process's (as before accounts existed).
//!
//! What each request needs ([`required`]): reading (`GET`, and an explicit Get) [`Action::View`];
//! outputs, breaker commands and recording [`Action::Operate`]; Set_Attribute and any other
//! state-changing request (configuration, scan-list edits) [`Action::Engineer`]. Every
//! state-changing request other than login / logout is recorded in the audit log
//! ([`crate::audit`]) with the user, node, what and result, refusals by role included.

use super::guard::{new_token, GuardError};
use super::http::{Request, Response};
use super::Context;
use crate::accounts::{Action, Role, Users};
use crate::audit::{AuditEntry, Via};
use serde_json::{json, Value};
use std::collections::HashMap;
use std::sync::{Mutex, PoisonError};
use std::time::{Duration, Instant};

/// The session cookie's name.
pub const COOKIE: &str = "dnet_session";
/// A session ends after this long without a request.
pub const SESSION_IDLE: Duration = Duration::from_secs(30 * 60);
/// Sessions kept at most; a login beyond them ends the least recently used.
pub const MAX_SESSIONS: usize = 64;

/// Who sent a request.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct Caller {
    /// The account (`-` without a users file).
    pub(crate) user: String,
    /// What it may do.
    pub(crate) role: Role,
    /// The CSRF token its state-changing requests carry.
    pub(crate) token: String,
}

struct Session {
    caller: Caller,
    last: Instant,
}

/// The console's accounts and sessions.
pub(crate) struct Auth {
    users: Option<Users>,
    sessions: Mutex<HashMap<String, Session>>,
    /// The token without a users file.
    process_token: String,
    /// Cookies get `Secure` (TLS is on).
    secure: bool,
}

/// What a request needs: its method and path (`/api/node/5/breaker/open`).
pub(crate) fn required(method: &str, path: &str) -> Action {
    if method == "GET" || method == "HEAD" {
        return Action::View;
    }
    // A network's request (`/api/net/NAME/...`) needs what the same request of one network does.
    let (_, path) = super::networks::split(path);
    let segments: Vec<&str> = path.split('/').filter(|s| !s.is_empty()).collect();
    match segments.as_slice() {
        ["api", "login" | "logout"] | ["api", "node", _, "get"] => Action::View,
        ["api", "node", _, "output"] | ["api", "node", _, "breaker", _] | ["api", "record", _] => {
            Action::Operate
        }
        // Set_Attribute, and whatever else changes state (configure, scan list): the most
        // privileged, so that a new route is closed until someone opens it.
        _ => Action::Engineer,
    }
}

fn cookie_value<'a>(headers: impl Iterator<Item = (&'a str, &'a str)>) -> Option<&'a str> {
    headers
        .filter(|(k, _)| k.eq_ignore_ascii_case("Cookie"))
        .flat_map(|(_, v)| v.split(';'))
        .find_map(|c| c.trim().strip_prefix(COOKIE)?.strip_prefix('='))
}

fn json_response(status: u16, value: &Value) -> Response {
    Response::new(status, "application/json", value.to_string().into_bytes())
}

impl Auth {
    /// Accounts from `users` (`None`: logins off, every caller anonymous with `process_token`).
    pub(crate) fn new(users: Option<Users>, process_token: String, secure: bool) -> Auth {
        Auth { users, sessions: Mutex::new(HashMap::new()), process_token, secure }
    }

    /// Whether logins are on.
    pub(crate) fn logins(&self) -> bool {
        self.users.is_some()
    }

    /// The token without a users file (empty with one: each session has its own).
    pub(crate) fn page_token(&self) -> &str {
        if self.logins() {
            ""
        } else {
            &self.process_token
        }
    }

    /// The caller of a request with these headers, if any (a live session, or anonymous without
    /// a users file). Looking a session up keeps it alive.
    pub(crate) fn caller<'a>(&self, headers: impl Iterator<Item = (&'a str, &'a str)>) -> Option<Caller> {
        if !self.logins() {
            return Some(Caller {
                user: "-".into(),
                role: Role::Engineer,
                token: self.process_token.clone(),
            });
        }
        let id = cookie_value(headers)?;
        let mut sessions = self.sessions.lock().unwrap_or_else(PoisonError::into_inner);
        let now = Instant::now();
        sessions.retain(|_, s| now.duration_since(s.last) < SESSION_IDLE);
        let session = sessions.get_mut(id)?;
        session.last = now;
        Some(session.caller.clone())
    }

    fn cookie(&self, id: &str, max_age: Option<u64>) -> String {
        let mut c = format!("{COOKIE}={id}; HttpOnly; SameSite=Strict; Path=/");
        if let Some(age) = max_age {
            c.push_str(&format!("; Max-Age={age}"));
        }
        if self.secure {
            c.push_str("; Secure");
        }
        c
    }

    /// `POST /api/login` `{"user", "password"}`: a new session and its cookie, or `401`.
    pub(crate) fn login(&self, body: &[u8]) -> (Response, Option<Caller>) {
        let Some(users) = &self.users else {
            let r = json_response(400, &json!({"ok": false, "error": "logins are off (no --users file)"}));
            return (r, None);
        };
        let parsed: Option<(String, String)> = serde_json::from_slice::<Value>(body).ok().and_then(|v| {
            Some((v.get("user")?.as_str()?.to_string(), v.get("password")?.as_str()?.to_string()))
        });
        let Some((user, password)) = parsed else {
            let r = json_response(400, &json!({"ok": false, "error": "expected {\"user\", \"password\"}"}));
            return (r, None);
        };
        let Some(role) = users.verify(&user, &password) else {
            let r = json_response(401, &json!({"ok": false, "error": "wrong user name or password"}));
            return (r, Some(Caller { user, role: Role::Viewer, token: String::new() }));
        };
        let (Ok(id), Ok(token)) = (new_token(), new_token()) else {
            return (json_response(500, &json!({"ok": false, "error": "no random session id"})), None);
        };
        let caller = Caller { user, role, token };
        {
            let mut sessions = self.sessions.lock().unwrap_or_else(PoisonError::into_inner);
            while sessions.len() >= MAX_SESSIONS {
                let oldest = sessions.iter().min_by_key(|(_, s)| s.last).map(|(k, _)| k.clone());
                match oldest {
                    Some(k) => sessions.remove(&k),
                    None => break,
                };
            }
            sessions.insert(id.clone(), Session { caller: caller.clone(), last: Instant::now() });
        }
        let mut r = json_response(200, &session_json(&caller));
        r.add_header("Set-Cookie", &self.cookie(&id, None));
        (r, Some(caller))
    }

    /// `POST /api/logout`: the session ends, the cookie is cleared.
    pub(crate) fn logout<'a>(&self, headers: impl Iterator<Item = (&'a str, &'a str)>) -> Response {
        if let Some(id) = cookie_value(headers) {
            self.sessions.lock().unwrap_or_else(PoisonError::into_inner).remove(id);
        }
        let mut r = json_response(200, &json!({"ok": true}));
        r.add_header("Set-Cookie", &self.cookie("", Some(0)));
        r
    }

    /// Sessions alive now.
    #[cfg(test)]
    fn live(&self) -> usize {
        self.sessions.lock().unwrap_or_else(PoisonError::into_inner).len()
    }
}

/// `{"ok", "user", "role", "token", "may": {"view", "operate", "engineer"}}`.
pub(crate) fn session_json(c: &Caller) -> Value {
    json!({
        "ok": true,
        "user": c.user,
        "role": c.role.name(),
        "token": c.token,
        "may": {
            "view": c.role.may(Action::View),
            "operate": c.role.may(Action::Operate),
            "engineer": c.role.may(Action::Engineer),
        },
    })
}

/// Checks the CSRF token of a state-changing request against the caller's.
pub(crate) fn check_token<'a>(
    caller: &Caller,
    mut headers: impl Iterator<Item = (&'a str, &'a str)>,
) -> Result<(), GuardError> {
    let token = headers
        .find(|(k, _)| k.eq_ignore_ascii_case(super::TOKEN_HEADER))
        .map(|(_, v)| v.trim())
        .ok_or(GuardError::NoToken)?;
    // Compared in time independent of where the first difference is.
    let same = !caller.token.is_empty()
        && token.len() == caller.token.len()
        && token.bytes().zip(caller.token.bytes()).fold(0u8, |acc, (a, b)| acc | (a ^ b)) == 0;
    if same {
        Ok(())
    } else {
        Err(GuardError::WrongToken)
    }
}

/// The audit entry of a console command: the node from the path, what from the path and body,
/// the result from the response.
pub(crate) fn audit_entry(user: &str, request: &Request, response: &Response) -> AuditEntry {
    let (network, path) = super::networks::split(request.url.split('?').next().unwrap_or(""));
    let segments: Vec<&str> = path.split('/').filter(|s| !s.is_empty()).collect();
    let (mac, what) = match segments.as_slice() {
        ["api", "node", mac, rest @ ..] => (mac.parse::<u8>().ok().filter(|m| *m <= 63), rest.join(" ")),
        ["api", rest @ ..] => (None, rest.join(" ")),
        _ => (None, path.clone()),
    };
    let what = match network {
        Some(name) => format!("net {name}: {what}"),
        None => what,
    };
    let body = String::from_utf8_lossy(&request.body);
    // The body tells the values (output image, attribute, parameter); never a login's password.
    let body = body.trim();
    let what =
        if body.is_empty() || body == "{}" || what == "login" { what } else { format!("{what} {body}") };
    let answer: Option<Value> = serde_json::from_slice(&response.body).ok();
    let ok = response.status == 200
        && answer.as_ref().and_then(|a| a.get("ok")).and_then(Value::as_bool) != Some(false);
    let reason = answer
        .as_ref()
        .and_then(|a| a.get("error"))
        .and_then(Value::as_str)
        .map_or_else(|| format!("status {}", response.status), str::to_string);
    let result = match response.status {
        _ if ok => "ok".to_string(),
        401 | 403 => format!("refused: {reason}"),
        _ => format!("failed: {reason}"),
    };
    AuditEntry::now(user, Via::Console, mac, &what, &result)
}

/// Whether a request is answered without a session: the page and its files, `GET /api/session`.
fn public(method: &str, path: &str) -> bool {
    (method == "GET" || method == "HEAD")
        && matches!(path, "/" | "/index.html" | "/app.js" | "/style.css" | "/favicon.ico" | "/api/session")
}

/// Admits a request that passed the guard: logs in and out, finds the caller, checks its token
/// and its role, then has `answer` answer it; records state-changing requests in the audit log.
pub(crate) fn admit(ctx: &Context, request: &Request, answer: impl FnOnce(&Caller) -> Response) -> Response {
    let path = request.url.split('?').next().unwrap_or("");
    let method = request.method.as_str();
    let changes = !(method == "GET" || method == "HEAD");
    if method == "POST" && path == "/api/login" {
        let (r, who) = ctx.auth.login(&request.body);
        if let Some(c) = who {
            record(ctx, &c.user, request, &r);
        }
        return r;
    }
    let Some(caller) = ctx.auth.caller(request.header_pairs()) else {
        if public(method, path) && path != "/api/session" {
            let nobody = Caller { user: String::new(), role: Role::Viewer, token: String::new() };
            return answer(&nobody);
        }
        return json_response(
            401,
            &json!({"ok": false, "login": true, "error": "not logged in (or the session ended): log in first"}),
        );
    };
    if method == "GET" && path == "/api/session" {
        return json_response(200, &session_json(&caller));
    }
    if changes {
        if let Err(e) = check_token(&caller, request.header_pairs()) {
            return json_response(403, &json!({"ok": false, "error": e.to_string()}));
        }
    }
    if method == "POST" && path == "/api/logout" {
        let r = ctx.auth.logout(request.header_pairs());
        record(ctx, &caller.user, request, &r);
        return r;
    }
    let action = required(method, path);
    let r = if caller.role.may(action) {
        answer(&caller)
    } else {
        let why = format!(
            "user {} has the role {}, which may not {} (needed for {method} {path})",
            caller.user,
            caller.role.name(),
            action.name()
        );
        json_response(403, &json!({"ok": false, "error": why, "role": caller.role.name()}))
    };
    if changes {
        record(ctx, &caller.user, request, &r);
    }
    r
}

/// Records a console request in the audit log; a log that cannot write does not fail it.
fn record(ctx: &Context, user: &str, request: &Request, response: &Response) {
    let _ = ctx.shared.audit.record(&audit_entry(user, request, response));
}

/// The requests answered here: `GET /api/token`, `GET /api/audit?limit=N` (newest first, default
/// 200, at most 2000).
pub(crate) fn route(ctx: &Context, caller: &Caller, request: &Request) -> Option<Response> {
    let (path, query) = request.url.split_once('?').unwrap_or((&request.url, ""));
    if request.method != "GET" && request.method != "HEAD" {
        return None;
    }
    match path {
        "/api/token" => Some(json_response(200, &json!({"ok": true, "token": caller.token}))),
        "/api/audit" => {
            let limit = query
                .split('&')
                .find_map(|p| p.strip_prefix("limit="))
                .map_or(Ok(AUDIT_DEFAULT), str::parse::<usize>);
            let Ok(limit) = limit else {
                return Some(json_response(
                    400,
                    &json!({"ok": false, "error": "bad limit: expected a number"}),
                ));
            };
            Some(match ctx.shared.audit.recent(limit.clamp(1, AUDIT_MAX)) {
                Ok(entries) => json_response(200, &json!({"ok": true, "entries": entries})),
                Err(e) => json_response(500, &json!({"ok": false, "error": e.to_string()})),
            })
        }
        _ => None,
    }
}

/// Audit entries `GET /api/audit` returns by default, and at most.
const AUDIT_DEFAULT: usize = 200;
const AUDIT_MAX: usize = 2000;

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;
    use std::path::Path;

    fn users() -> Users {
        let mut u = Users::empty(Path::new("users.toml"));
        u.add("op", "pw-op", Role::Operator).unwrap();
        u
    }

    #[rstest]
    #[case::state("GET", "/api/state", Action::View)]
    #[case::get("POST", "/api/node/5/get", Action::View)]
    #[case::output("POST", "/api/node/5/output", Action::Operate)]
    #[case::close("POST", "/api/node/5/breaker/close", Action::Operate)]
    #[case::record("POST", "/api/record/start", Action::Operate)]
    #[case::set("POST", "/api/node/5/set", Action::Engineer)]
    #[case::unknown("POST", "/api/scanlist/edit", Action::Engineer)]
    fn what_each_request_needs(#[case] method: &str, #[case] path: &str, #[case] action: Action) {
        assert_eq!(required(method, path), action);
    }

    #[test]
    fn login_session_logout() {
        let auth = Auth::new(Some(users()), "p".into(), true);
        assert_eq!(auth.caller([("Cookie", "dnet_session=nope")].into_iter()), None);
        let (r, c) = auth.login(br#"{"user":"op","password":"wrong"}"#);
        assert_eq!(r.status, 401);
        assert_eq!(c.map(|c| c.user), Some("op".to_string()));
        let (r, c) = auth.login(br#"{"user":"op","password":"pw-op"}"#);
        assert_eq!(r.status, 200);
        let c = c.unwrap();
        assert_eq!(c.role, Role::Operator);
        let text = format!("{r:?}");
        let id = text.split("dnet_session=").nth(1).unwrap().split(';').next().unwrap().to_string();
        assert!(text.contains("HttpOnly; SameSite=Strict; Path=/; Secure"), "{text}");
        let cookie = format!("a=b; dnet_session={id}");
        let found = auth.caller([("Cookie", cookie.as_str())].into_iter()).unwrap();
        assert_eq!(found, c);
        assert_eq!(check_token(&found, [("X-CSRF-Token", c.token.as_str())].into_iter()), Ok(()));
        assert_eq!(check_token(&found, [("X-CSRF-Token", "p")].into_iter()), Err(GuardError::WrongToken));
        auth.logout([("Cookie", cookie.as_str())].into_iter());
        assert_eq!(auth.caller([("Cookie", cookie.as_str())].into_iter()), None);
    }

    #[test]
    fn sessions_are_bounded() {
        let auth = Auth::new(Some(users()), "p".into(), false);
        for _ in 0..MAX_SESSIONS + 3 {
            assert_eq!(auth.login(br#"{"user":"op","password":"pw-op"}"#).0.status, 200);
        }
        assert_eq!(auth.live(), MAX_SESSIONS);
    }

    #[test]
    fn without_users_everyone_is_anonymous_with_the_process_token() {
        let auth = Auth::new(None, "tok".into(), false);
        let c = auth.caller(std::iter::empty()).unwrap();
        assert_eq!((c.user.as_str(), c.role, c.token.as_str()), ("-", Role::Engineer, "tok"));
        assert_eq!(auth.page_token(), "tok");
    }
}
