//! Several networks behind one console (`dnet-master ui --plant FILE.toml`, [`crate::plant`]).
//!
//! Each network has its own [`Shared`] (state, frames, commands, history), filled by its own
//! scanner loop. The console's API of one network is the single-network API under
//! `/api/net/NAME/`: `GET /api/net/line-b/state`, `POST /api/net/line-b/node/5/breaker/open`.
//! The unprefixed API (`/api/state`, `/api/node/5/...`) is the first network's, so the page and
//! scripts written for one network keep working. `GET /api/state` also carries `networks`: each
//! network's name, bus and state ([`ConsoleNetwork`]); `GET /api/networks` lists them alone.
//! Logins, roles, CSRF and the guard apply to every network's requests as to one; the audit log
//! names the network in what was done (`net line-b: breaker open`).

use super::Context;
use crate::model::Shared;
use serde_json::{json, Map, Value};
use std::sync::Arc;

/// One network as the console serves it.
#[derive(Clone)]
pub struct ConsoleNetwork {
    /// Its name (`[A-Za-z0-9_-]`, [`crate::plant::valid_name`]).
    pub name: String,
    /// Its bus as written in the plant file.
    pub bus: String,
    /// What its scanner loop shares with the console.
    pub shared: Arc<Shared>,
}

/// A network's request handler context (its own [`Context`], sharing nothing with the others but
/// the process's token).
pub(crate) struct NetworkContext {
    pub(crate) name: String,
    pub(crate) bus: String,
    pub(crate) context: Arc<Context>,
}

/// Splits `/api/net/NAME/rest` into `(Some(NAME), "/api/rest")`; any other path is returned as it
/// is with `None`.
pub(crate) fn split(path: &str) -> (Option<&str>, String) {
    let Some(after) = path.strip_prefix("/api/net/") else {
        return (None, path.to_string());
    };
    let (name, rest) = after.split_once('/').unwrap_or((after, ""));
    (Some(name), format!("/api/{rest}"))
}

/// Where a `/api/net/NAME/...` request goes: the network's context and the request's URL within
/// it (`/api/rest?query`), or why there is none (an unknown network: the plant's are named).
/// `None` for any other request.
pub(crate) fn target(ctx: &Context, url: &str) -> Option<Result<(Arc<Context>, String), String>> {
    let (path, query) = url.split_once('?').map_or((url, None), |(p, q)| (p, Some(q)));
    let (Some(name), rest) = split(path) else {
        return None;
    };
    let Some(network) = ctx.networks.iter().find(|n| n.name == name) else {
        let known: Vec<&str> = ctx.networks.iter().map(|n| n.name.as_str()).collect();
        return Some(Err(if known.is_empty() {
            format!("no network {name:?}: this console runs one network (no --plant)")
        } else {
            format!("no network {name:?}: the plant's networks are {}", known.join(", "))
        }));
    };
    let url = match query {
        Some(q) => format!("{rest}?{q}"),
        None => rest,
    };
    Some(Ok((Arc::clone(&network.context), url)))
}

/// `GET /api/networks`: the networks' names and buses (empty without a plant).
pub(crate) fn list(ctx: &Context) -> Value {
    let networks: Vec<Value> = ctx.networks.iter().map(|n| json!({"name": n.name, "bus": n.bus})).collect();
    json!({"ok": true, "networks": networks})
}

/// Adds `networks` (each network's name, bus and state) to `GET /api/state`'s answer; nothing
/// without a plant.
pub(crate) fn add_to_state(ctx: &Context, map: &mut Map<String, Value>) {
    if ctx.networks.is_empty() {
        return;
    }
    let networks = ctx
        .networks
        .iter()
        .map(|n| {
            let mut v = match n.context.shared.state.lock() {
                Ok(s) => serde_json::to_value(&*s).unwrap_or(Value::Null),
                Err(_) => json!({"error": "the scanner's state is unavailable"}),
            };
            if let Value::Object(m) = &mut v {
                m.insert("name".into(), Value::String(n.name.clone()));
                m.insert("bus".into(), Value::String(n.bus.clone()));
            }
            v
        })
        .collect();
    map.insert("networks".into(), Value::Array(networks));
}

#[cfg(test)]
mod tests {
    use super::split;

    #[test]
    fn network_paths_are_split() {
        assert_eq!(
            split("/api/net/line-b/node/5/breaker/open"),
            (Some("line-b"), "/api/node/5/breaker/open".into())
        );
        assert_eq!(split("/api/net/a/state"), (Some("a"), "/api/state".into()));
        assert_eq!(split("/api/net/a"), (Some("a"), "/api/".into()));
        assert_eq!(split("/api/node/5/get"), (None, "/api/node/5/get".into()));
        assert_eq!(split("/api/network"), (None, "/api/network".into()));
    }
}
