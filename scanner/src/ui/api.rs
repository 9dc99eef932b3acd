//! The console's requests: routing, the JSON API and the embedded assets (see the [module
//! docs](super)). Every handler returns a response or an [`ApiError`]; nothing here panics on
//! what a client sends.

use super::http::{Request, Response};
use super::record::Recorder;
use super::{Context, COMMAND_TIMEOUT, MAX_EXPORT};
use crate::breaker::{breaker_output, BreakerCommand};
use crate::model::{ConsoleCommand, NodeState, Reply, Shared};
use crate::monitor::{Field, ImageProfile, InputLayout, LinkView};
use crate::params::{decode_value, ParamRow, PARAMETER_CLASS};
use master_core::decode::short_string;
use serde_json::{json, Value};
use slave_fw::description::DeviceDescription;
use std::io::Write;
use std::sync::mpsc;
use std::sync::{Arc, OnceLock};

const INDEX_HTML: &str = include_str!("assets/index.html");
const APP_JS: &str = include_str!("assets/app.js");
const STYLE_CSS: &str = include_str!("assets/style.css");
/// Where the served page carries the token (`<meta name="csrf-token" content="...">`).
const TOKEN_PLACEHOLDER: &str = "{{CSRF_TOKEN}}";
const MODBUS_METER: &str = include_str!("../../../slave-fw/descriptions/modbus-meter.toml");

/// Frames returned by one `/api/frames` by default, and at most.
const FRAMES_DEFAULT: usize = 500;
const FRAMES_MAX: usize = crate::model::FRAME_RING;
/// Samples returned by one `/api/history` by default, and at most.
const HISTORY_DEFAULT: usize = 2000;
const HISTORY_MAX: usize = 20_000;
/// Parameter instances read at most.
const PARAMS_MAX: u16 = 64;

/// Bytes as hex digits without spaces (`0201000000000000`), as the API takes them.
fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02X}")).collect()
}

/// A refused request: the HTTP status and the reason in words.
#[derive(Debug)]
pub(crate) struct ApiError {
    pub(crate) status: u16,
    pub(crate) message: String,
}

fn err(status: u16, message: impl Into<String>) -> ApiError {
    ApiError { status, message: message.into() }
}

type Resp = Response;

fn bytes_response(status: u16, content_type: &str, body: Vec<u8>) -> Resp {
    Response::new(status, content_type, body)
}

pub(crate) fn json_response(status: u16, value: &Value) -> Resp {
    bytes_response(status, "application/json", value.to_string().into_bytes())
}

/// `{"ok": false, "error": message}` with `status`.
pub(crate) fn error_response(status: u16, message: &str) -> Resp {
    json_response(status, &json!({"ok": false, "error": message}))
}

/// Answers one request (on a worker of the server): the guard's checks ([`super::guard`]), then
/// the route.
pub(crate) fn handle(ctx: &Arc<Context>, request: &Request) -> Resp {
    if let Err(e) = ctx.guard.check(&request.method, request.header_pairs()) {
        return error_response(403, &e.to_string());
    }
    super::auth::admit(ctx, request, |caller| {
        super::auth::route(ctx, caller, request).unwrap_or_else(|| {
            // A network's request (`/api/net/NAME/...`, `ui --plant`) is answered by its own context.
            let routed = match super::networks::target(ctx, &request.url) {
                None => route(ctx, &request.method, &request.url, &request.body),
                Some(Ok((network, url))) => route(&network, &request.method, &url, &request.body),
                Some(Err(message)) => Err(err(404, message)),
            };
            routed.unwrap_or_else(|e| error_response(e.status, &e.message))
        })
    })
}

/// The query parameter `name`, percent-decoded.
fn query<'a>(pairs: &'a [(String, String)], name: &str) -> Option<&'a str> {
    pairs.iter().find(|(k, _)| k == name).map(|(_, v)| v.as_str())
}

fn percent_decode(s: &str) -> String {
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        match bytes[i] {
            b'+' => out.push(b' '),
            b'%' if i + 2 < bytes.len() => match u8::from_str_radix(s.get(i + 1..i + 3).unwrap_or(""), 16) {
                Ok(b) => {
                    out.push(b);
                    i += 2;
                }
                Err(_) => out.push(b'%'),
            },
            b => out.push(b),
        }
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

fn parse_query(q: &str) -> Vec<(String, String)> {
    q.split('&')
        .filter(|p| !p.is_empty())
        .map(|p| {
            let (k, v) = p.split_once('=').unwrap_or((p, ""));
            (percent_decode(k), percent_decode(v))
        })
        .collect()
}

/// A number parameter: absent → `None`; present and malformed → an error naming it.
fn number<T: std::str::FromStr>(pairs: &[(String, String)], name: &str) -> Result<Option<T>, ApiError> {
    match query(pairs, name) {
        None | Some("") => Ok(None),
        Some(v) => v.parse().map(Some).map_err(|_| err(400, format!("bad {name} {v:?}: expected a number"))),
    }
}

fn parse_mac(text: &str) -> Result<u8, ApiError> {
    match text.parse::<u8>() {
        Ok(m) if m <= 63 => Ok(m),
        _ => Err(err(400, format!("bad MAC {text:?}: expected 0..=63"))),
    }
}

fn query_mac(pairs: &[(String, String)]) -> Result<Option<u8>, ApiError> {
    match query(pairs, "mac") {
        None | Some("") => Ok(None),
        Some(m) => parse_mac(m).map(Some),
    }
}

/// Bytes from hex (spaces, `0x` and a trailing newline allowed).
fn parse_hex(text: &str) -> Result<Vec<u8>, ApiError> {
    let t = text.trim();
    let t = t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")).unwrap_or(t);
    let digits: Vec<u8> = t.bytes().filter(|b| !b.is_ascii_whitespace()).collect();
    let bad =
        || err(400, format!("bad hex {:?}: expected pairs of hex digits (0201000000000000)", text.trim()));
    if digits.len() % 2 != 0 {
        return Err(bad());
    }
    digits
        .chunks(2)
        .map(|p| std::str::from_utf8(p).ok().and_then(|s| u8::from_str_radix(s, 16).ok()).ok_or_else(bad))
        .collect()
}

fn parse_json(body: &[u8]) -> Result<Value, ApiError> {
    serde_json::from_slice(body).map_err(|e| err(400, format!("bad JSON body: {e}")))
}

/// A whole-number field of a JSON body (a number, or a string in decimal or `0x` hex).
fn json_uint(body: &Value, name: &str, max: u64) -> Result<u64, ApiError> {
    let v = body.get(name).ok_or_else(|| err(400, format!("missing {name:?}")))?;
    let n = match v {
        Value::Number(n) => n.as_u64(),
        Value::String(s) => {
            let s = s.trim();
            match s.strip_prefix("0x").or_else(|| s.strip_prefix("0X")) {
                Some(h) => u64::from_str_radix(h, 16).ok(),
                None => s.parse().ok(),
            }
        }
        _ => None,
    };
    match n {
        Some(n) if n <= max => Ok(n),
        _ => Err(err(400, format!("bad {name} {v}: expected 0..={max}"))),
    }
}

fn route(ctx: &Arc<Context>, method: &str, url: &str, body: &[u8]) -> Result<Resp, ApiError> {
    let (path, q) = url.split_once('?').unwrap_or((url, ""));
    let pairs = parse_query(q);
    let segments: Vec<&str> = path.split('/').filter(|s| !s.is_empty()).collect();
    let shared = &ctx.shared;
    let get = method == "GET" || method == "HEAD";
    let post = method == "POST";
    let wrong = || err(405, format!("{method} is not allowed on {path}"));
    match segments.as_slice() {
        [] | ["index.html"] if get => Ok(bytes_response(
            200,
            "text/html; charset=utf-8",
            INDEX_HTML.replace(TOKEN_PLACEHOLDER, ctx.auth.page_token()).into(),
        )),
        ["app.js"] if get => Ok(bytes_response(200, "text/javascript; charset=utf-8", APP_JS.into())),
        ["style.css"] if get => Ok(bytes_response(200, "text/css; charset=utf-8", STYLE_CSS.into())),
        ["favicon.ico"] => Ok(bytes_response(204, "image/x-icon", Vec::new())),
        [] | ["index.html"] | ["app.js"] | ["style.css"] => Err(wrong()),
        ["api", rest @ ..] => match (rest, get, post) {
            (["state"], true, _) => Ok(json_response(200, &state(ctx))),
            (["frames"], true, _) => frames(shared, &pairs),
            (["node", mac], true, _) => node(shared, parse_mac(mac)?),
            (["node", mac, "params"], true, _) => params(shared, parse_mac(mac)?),
            (["node", mac, "serial-trace"], true, _) => Ok(super::serial_trace_api::poll(
                shared,
                &ctx.serial_traces,
                parse_mac(mac)?,
                number(&pairs, "since")?,
            )),
            (["node", mac, "output"], _, true) => {
                let mac = parse_mac(mac)?;
                let data = match parse_json(body)? {
                    Value::String(s) => parse_hex(&s)?,
                    Value::Object(o) => match o.get("data") {
                        Some(Value::String(s)) => parse_hex(s)?,
                        _ => return Err(err(400, "missing \"data\": the output image in hex")),
                    },
                    _ => return Err(err(400, "expected {\"data\": hex}: the output image in hex")),
                };
                set_output(shared, mac, data)
            }
            (["node", mac, "get"], _, true) => explicit_get(shared, parse_mac(mac)?, &parse_json(body)?),
            (["node", mac, "set"], _, true) => explicit_set(shared, parse_mac(mac)?, &parse_json(body)?),
            (["node", mac, "breaker", action], _, true) => breaker(shared, parse_mac(mac)?, action, body),
            (["history"], true, _) => history(shared, &pairs),
            (["export.csv"], true, _) => export_csv(shared, &pairs),
            (["record"], true, _) => Ok(json_response(200, &record_status(ctx))),
            (["record", "start"], _, true) => record_start(ctx),
            (["record", "stop"], _, true) => record_stop(ctx),
            (["health"], true, _) => Ok(super::health_api::report(shared, false)),
            (["health.csv"], true, _) => Ok(super::health_api::csv(shared)),
            (["health", "clear"], _, true) => Ok(super::health_api::report(shared, true)),
            (["health"] | ["health.csv"] | ["health", "clear"], _, _) => Err(wrong()),
            (["events"], true, _) => Ok(super::scanlist_api::events(shared, number(&pairs, "since")?)),
            (["scanlist", action], _, true) => Ok(super::scanlist_api::edit(shared, action, body)),
            (["events"] | ["scanlist", _], _, _) => Err(wrong()),
            (["project", "compare"], true, _) => {
                Ok(super::project_api::compare(shared, ctx.project.as_ref()))
            }
            (["project", "compare"], _, _) => Err(wrong()),
            (["networks"], true, _) => Ok(json_response(200, &super::networks::list(ctx))),
            (["networks"], _, _) => Err(wrong()),
            (
                ["state"]
                | ["token"]
                | ["frames"]
                | ["node", _]
                | ["node", _, "params" | "output" | "get" | "set" | "serial-trace"]
                | ["node", _, "breaker", _]
                | ["history"]
                | ["export.csv"]
                | ["record"]
                | ["record", "start" | "stop"],
                _,
                _,
            ) => Err(wrong()),
            _ => Err(err(404, format!("no such API: {path}"))),
        },
        _ => Err(err(404, format!("not found: {path}"))),
    }
}

fn state(ctx: &Context) -> Value {
    let shared = &ctx.shared;
    let mut v = match shared.state.lock() {
        Ok(s) => serde_json::to_value(&*s).unwrap_or(Value::Null),
        Err(_) => json!({"error": "the scanner's state is unavailable"}),
    };
    if let Value::Object(map) = &mut v {
        map.insert(
            "mqtt".into(),
            shared.mqtt.lock().ok().and_then(|m| m.clone()).map_or(Value::Null, Value::String),
        );
        map.insert("recording".into(), Value::Bool(ctx.recorder.lock().is_ok_and(|r| r.is_some())));
        map.insert("history".into(), Value::Bool(shared.history.is_some()));
        map.insert("ok".into(), Value::Bool(true));
        super::networks::add_to_state(ctx, map);
    }
    v
}

fn frames(shared: &Shared, pairs: &[(String, String)]) -> Result<Resp, ApiError> {
    let after: u64 = number(pairs, "after")?.unwrap_or(0);
    let mac = query_mac(pairs)?;
    let kind = query(pairs, "kind").filter(|k| !k.is_empty());
    let limit = number::<usize>(pairs, "limit")?.unwrap_or(FRAMES_DEFAULT).clamp(1, FRAMES_MAX);
    let ring = shared.frames.lock().map_err(|_| err(500, "the frame ring is unavailable"))?;
    let next = ring.back().map_or(after, |f| f.seq.max(after));
    let mut rows: Vec<&crate::model::FrameRow> = ring
        .iter()
        .rev()
        .filter(|f| f.seq > after)
        .filter(|f| mac.is_none() || f.mac == mac)
        .filter(|f| kind.is_none_or(|k| f.kind == k))
        .take(limit)
        .collect();
    rows.reverse();
    let v = json!({"ok": true, "next": next, "frames": rows});
    drop(ring);
    Ok(json_response(200, &v))
}

fn find_node(shared: &Shared, mac: u8) -> Result<NodeState, ApiError> {
    let state = shared.state.lock().map_err(|_| err(500, "the scanner's state is unavailable"))?;
    state
        .nodes
        .iter()
        .find(|n| n.mac == mac)
        .cloned()
        .ok_or_else(|| err(404, format!("MAC {mac} is not in the scan list")))
}

/// The descriptions the console recognises a node by: the reference breaker converter and the
/// Modbus meter gateway of `slave-fw/descriptions/`.
pub fn known_descriptions() -> &'static [DeviceDescription] {
    static KNOWN: OnceLock<Vec<DeviceDescription>> = OnceLock::new();
    KNOWN.get_or_init(|| {
        let mut v = vec![DeviceDescription::reference()];
        v.extend(DeviceDescription::parse(MODBUS_METER).ok());
        v
    })
}

/// How the console decodes `node`'s input image: the known description whose vendor, product code
/// and product name match the identity read, with the status byte and freshness counter when the
/// node's input size says the input assembly carries them (image + 2); raw bytes otherwise.
pub fn layout_for(node: &NodeState, descriptions: &[DeviceDescription]) -> InputLayout {
    let id = &node.identity;
    for d in descriptions {
        let known = &d.converter.device.identity;
        let same = id.vendor_id == Some(known.vendor_id)
            && id.product_code == Some(known.product_code)
            && id.product_name.as_deref().is_none_or(|n| n == known.product_name.as_str());
        if !same {
            continue;
        }
        let mut layout = InputLayout::from_converter(&d.converter);
        let size =
            node.input_size.map(usize::from).or_else(|| (!node.input.is_empty()).then_some(node.input.len()));
        match size {
            Some(s) if s == layout.image_len => layout.with_status = false,
            Some(s) if s == layout.image_len + 2 => layout.with_status = true,
            _ => {}
        }
        return layout;
    }
    InputLayout::raw()
}

fn profile_name(layout: &InputLayout) -> &'static str {
    match layout.profile {
        ImageProfile::Raw => "raw",
        ImageProfile::Breaker => "breaker",
        ImageProfile::Framed => "framed",
        ImageProfile::Modbus { .. } => "modbus",
    }
}

/// The breaker's parameters 0–3 (image bytes 10–17, little-endian).
fn breaker_params(image: &[u8]) -> Vec<Field> {
    (0..4)
        .filter_map(|i| {
            let b = image.get(10 + 2 * i..12 + 2 * i)?;
            let v = u16::from_le_bytes([b[0], b[1]]);
            Some(Field { name: format!("param_{i}"), values: vec![v], text: v.to_string() })
        })
        .collect()
}

fn node(shared: &Shared, mac: u8) -> Result<Resp, ApiError> {
    let node = find_node(shared, mac)?;
    let layout = layout_for(&node, known_descriptions());
    let decoded = layout.decode(&node.input);
    let mut fields = decoded.fields;
    if layout.profile == ImageProfile::Breaker && decoded.note.is_none() {
        fields.extend(breaker_params(node.input.get(..layout.image_len).unwrap_or_default()));
    }
    // Raw data: still name the status byte and freshness counter when the produced size says
    // assembly 101 of a known image.
    let link = decoded.link.or_else(|| match (&layout.profile, node.input.as_slice()) {
        (ImageProfile::Raw, _) => None,
        (_, input) if input.len() == layout.image_len + 2 => {
            Some(LinkView::new(input[layout.image_len], input[layout.image_len + 1]))
        }
        _ => None,
    });
    let v = json!({
        "ok": true,
        "node": node,
        "profile": profile_name(&layout),
        "with_status": layout.with_status,
        "fields": fields,
        "link": link.map(|l| json!({
            "status": l.status, "freshness": l.freshness, "link": l.link, "errors_seen": l.errors_seen,
            "exception": l.exception, "request_unanswered": l.request_unanswered,
            "command": l.command, "stale": l.stale(), "text": l.text(),
        })),
        "note": decoded.note,
        "input_hex": hex(&node.input),
        "output_hex": hex(&node.output),
    });
    Ok(json_response(200, &v))
}

/// Sends a command to the scanner's loop and waits for its answer.
fn command(
    shared: &Shared,
    make: impl FnOnce(mpsc::Sender<Reply>) -> ConsoleCommand,
) -> Result<Vec<u8>, ApiError> {
    let (tx, rx) = mpsc::channel();
    shared
        .commands
        .lock()
        .map_err(|_| err(503, "the scanner is not taking commands"))?
        .send(make(tx))
        .map_err(|_| err(503, "the scanner is not running"))?;
    match rx.recv_timeout(COMMAND_TIMEOUT) {
        Ok(Ok(data)) => Ok(data),
        Ok(Err(e)) => Err(err(409, e)),
        Err(mpsc::RecvTimeoutError::Timeout) => {
            Err(err(504, format!("no answer from the scanner within {} s", COMMAND_TIMEOUT.as_secs())))
        }
        Err(mpsc::RecvTimeoutError::Disconnected) => Err(err(503, "the scanner stopped before answering")),
    }
}

fn set_output(shared: &Shared, mac: u8, data: Vec<u8>) -> Result<Resp, ApiError> {
    find_node(shared, mac)?;
    let text = hex(&data);
    command(shared, |reply| ConsoleCommand::SetOutput { mac, data, reply })?;
    Ok(json_response(200, &json!({"ok": true, "data": text})))
}

fn explicit_get(shared: &Shared, mac: u8, body: &Value) -> Result<Resp, ApiError> {
    let class = json_uint(body, "class", 0xFFFF)? as u16;
    let instance = json_uint(body, "instance", 0xFFFF)? as u16;
    let attribute = json_uint(body, "attribute", 0xFF)? as u8;
    find_node(shared, mac)?;
    let data = command(shared, |reply| ConsoleCommand::Get { mac, class, instance, attribute, reply })?;
    let text = master_core::decode::value_text(class, instance, attribute, &data);
    Ok(json_response(200, &json!({"ok": true, "data": hex(&data), "text": text})))
}

fn explicit_set(shared: &Shared, mac: u8, body: &Value) -> Result<Resp, ApiError> {
    let class = json_uint(body, "class", 0xFFFF)? as u16;
    let instance = json_uint(body, "instance", 0xFFFF)? as u16;
    let attribute = json_uint(body, "attribute", 0xFF)? as u8;
    let value = match body.get("value") {
        Some(Value::String(s)) => parse_hex(s)?,
        _ => return Err(err(400, "missing \"value\": the value's bytes in hex")),
    };
    find_node(shared, mac)?;
    let data =
        command(shared, |reply| ConsoleCommand::Set { mac, class, instance, attribute, value, reply })?;
    Ok(json_response(200, &json!({"ok": true, "data": hex(&data)})))
}

/// The breaker's commands through the output image (guide: docs/src/reference/io-data.md,
/// "Commands through the poll output"):
/// byte 0 the command, byte 1 the sequence number (bumped, so the converter executes it), bytes 2–4
/// the parameter id and value.
fn breaker(shared: &Shared, mac: u8, action: &str, body: &[u8]) -> Result<Resp, ApiError> {
    let breaker_command = match action {
        "open" => BreakerCommand::Open,
        "close" => BreakerCommand::Close,
        "param" => {
            let b = parse_json(body)?;
            let id = json_uint(&b, "id", 0xFF)? as u8;
            let value = json_uint(&b, "value", 0xFFFF)? as u16;
            BreakerCommand::SetParameter { id, value }
        }
        other => return Err(err(404, format!("no breaker command {other:?}: open, close or param"))),
    };
    let node = find_node(shared, mac)?;
    let layout = layout_for(&node, known_descriptions());
    if layout.profile != ImageProfile::Breaker {
        return Err(err(409, format!("MAC {mac} is not a breaker (profile {})", profile_name(&layout))));
    }
    let data = breaker_output(breaker_command, &node.output, node.output_size);
    let sequence = data.get(1).copied().unwrap_or(0);
    let text = hex(&data);
    command(shared, |reply| ConsoleCommand::SetOutput { mac, data, reply })?;
    Ok(json_response(200, &json!({"ok": true, "data": text, "command": action, "sequence": sequence})))
}

fn params(shared: &Shared, mac: u8) -> Result<Resp, ApiError> {
    find_node(shared, mac)?;
    let get = |instance: u16, attribute: u8| {
        command(shared, |reply| ConsoleCommand::Get {
            mac,
            class: PARAMETER_CLASS,
            instance,
            attribute,
            reply,
        })
    };
    let count = match get(0, 2) {
        Ok(d) if d.len() >= 2 => u16::from_le_bytes([d[0], d[1]]),
        Ok(_) => 0,
        Err(e) => {
            let v = json!({"ok": true, "params": [], "note": format!("none: {}", e.message)});
            return Ok(json_response(200, &v));
        }
    };
    let mut rows = Vec::new();
    for instance in 1..=count.min(PARAMS_MAX) {
        let opt = |a| get(instance, a).unwrap_or_default();
        let value = get(instance, 1)?;
        let data_type = opt(5).first().copied().unwrap_or(0);
        let descriptor = opt(4);
        rows.push(ParamRow {
            number: u32::from(instance),
            name: short_string(&opt(7)).unwrap_or_default(),
            path: (PARAMETER_CLASS, instance, 1),
            value: decode_value(data_type, &value),
            raw: hex(&value),
            units: short_string(&opt(8)).unwrap_or_default(),
            min: decode_value(data_type, &opt(10)),
            max: decode_value(data_type, &opt(11)),
            default: decode_value(data_type, &opt(12)),
            data_type,
            size: opt(6).first().copied().unwrap_or(0),
            read_only: descriptor.first().is_some_and(|d| d & 0x10 != 0),
        });
    }
    let note =
        if count == 0 { Some("none: the Parameter object has no instances".to_string()) } else { None };
    Ok(json_response(200, &json!({"ok": true, "params": rows, "note": note})))
}

/// `from` and `to` in ms (default: the last 60 s up to now).
fn time_range(pairs: &[(String, String)]) -> Result<(i64, i64), ApiError> {
    let now = crate::model::unix_ms_now();
    let to = number::<i64>(pairs, "to")?.unwrap_or(now);
    let from = number::<i64>(pairs, "from")?.unwrap_or(to.saturating_sub(60_000));
    if from > to {
        return Err(err(400, format!("from {from} is after to {to}")));
    }
    Ok((from, to))
}

fn history_store(shared: &Shared) -> Result<&dyn crate::model::HistoryStore, ApiError> {
    shared
        .history
        .as_deref()
        .ok_or_else(|| err(503, "no history is kept (start the console with a history database)"))
}

fn history(shared: &Shared, pairs: &[(String, String)]) -> Result<Resp, ApiError> {
    let mac = query_mac(pairs)?.ok_or_else(|| err(400, "missing mac"))?;
    let (from, to) = time_range(pairs)?;
    let limit = number::<usize>(pairs, "limit")?.unwrap_or(HISTORY_DEFAULT).clamp(1, HISTORY_MAX);
    let samples = history_store(shared)?.samples(mac, from, to, limit).map_err(|e| err(500, e))?;
    let rows: Vec<Value> = samples
        .iter()
        .map(
            |s| json!({"unix_ms": s.unix_ms, "bus_us": s.bus_us, "input": hex(&s.input), "values": s.values}),
        )
        .collect();
    Ok(json_response(200, &json!({"ok": true, "mac": mac, "from": from, "to": to, "samples": rows})))
}

/// A writer that refuses to grow past [`MAX_EXPORT`].
struct Capped(Vec<u8>);

impl Write for Capped {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        if self.0.len() + buf.len() > MAX_EXPORT {
            return Err(std::io::Error::other("export too large"));
        }
        self.0.extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

fn export_csv(shared: &Shared, pairs: &[(String, String)]) -> Result<Resp, ApiError> {
    let mac = query_mac(pairs)?;
    let (from, to) = time_range(pairs)?;
    let store = history_store(shared)?;
    let mut out = Capped(Vec::new());
    store.export_csv(mac, from, to, &mut out).map_err(|e| {
        if out.0.len() + 4096 > MAX_EXPORT {
            err(413, format!("the export is larger than {} MiB: choose a shorter range", MAX_EXPORT >> 20))
        } else {
            err(500, e)
        }
    })?;
    let name = match mac {
        Some(m) => format!("history-mac{m}-{from}-{to}.csv"),
        None => format!("history-{from}-{to}.csv"),
    };
    let mut r = bytes_response(200, "text/csv; charset=utf-8", out.0);
    r.add_header("Content-Disposition", &format!("attachment; filename=\"{name}\""));
    Ok(r)
}

fn record_status(ctx: &Context) -> Value {
    match ctx.recorder.lock().ok().and_then(|r| r.as_ref().map(Recorder::status)) {
        Some(s) => json!({"ok": true, "recording": true, "log": s.log, "pcap": s.pcap, "frames": s.frames,
                          "missed": s.missed, "error": s.error}),
        None => json!({"ok": true, "recording": false}),
    }
}

fn record_start(ctx: &Context) -> Result<Resp, ApiError> {
    let mut slot = ctx.recorder.lock().map_err(|_| err(500, "the recorder is unavailable"))?;
    if let Some(r) = slot.as_ref() {
        let s = r.status();
        return Err(err(409, format!("already recording to {} and {}", s.log, s.pcap)));
    }
    let r = Recorder::start(Arc::clone(&ctx.shared)).map_err(|e| err(500, e))?;
    let s = r.status();
    *slot = Some(r);
    Ok(json_response(200, &json!({"ok": true, "recording": true, "log": s.log, "pcap": s.pcap, "frames": 0})))
}

fn record_stop(ctx: &Context) -> Result<Resp, ApiError> {
    let r = ctx
        .recorder
        .lock()
        .map_err(|_| err(500, "the recorder is unavailable"))?
        .take()
        .ok_or_else(|| err(409, "not recording"))?;
    let s = r.stop();
    Ok(json_response(
        200,
        &json!({"ok": s.error.is_none(), "recording": false, "log": s.log, "pcap": s.pcap, "frames": s.frames,
                "missed": s.missed, "error": s.error}),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hex_is_parsed_or_refused() {
        assert_eq!(parse_hex("0201 0000\n").unwrap(), vec![2, 1, 0, 0]);
        assert_eq!(parse_hex("0x0a").unwrap(), vec![10]);
        assert_eq!(parse_hex("").unwrap(), Vec::<u8>::new());
        assert!(parse_hex("0g").is_err());
        assert!(parse_hex("abc").is_err());
        assert!(parse_hex("é1").is_err());
    }

    #[test]
    fn queries_are_decoded() {
        let q = parse_query("mac=5&kind=io%20x&x&bad=%zz&end=%4");
        assert_eq!(query(&q, "mac"), Some("5"));
        assert_eq!(query(&q, "kind"), Some("io x"));
        assert_eq!(query(&q, "x"), Some(""));
        assert_eq!(query(&q, "bad"), Some("%zz"));
        assert_eq!(query(&q, "end"), Some("%4"));
    }

    fn node(vendor: u16, product_code: u16, name: &str, input_size: u16) -> NodeState {
        NodeState {
            mac: 5,
            name: None,
            connection: "poll".into(),
            ack_suppression: false,
            status: crate::model::NodeStatus::Ok,
            code: 0,
            detail: None,
            identity: crate::model::Identity {
                vendor_id: Some(vendor),
                product_code: Some(product_code),
                product_name: Some(name.into()),
                ..Default::default()
            },
            input_size: Some(input_size),
            output_size: Some(8),
            input: Vec::new(),
            output: Vec::new(),
            exchanges: 0,
            last_exchange_us: None,
        }
    }

    #[test]
    fn nodes_are_recognised_by_identity_and_size() {
        let known = known_descriptions();
        assert_eq!(known.len(), 2, "the breaker and the Modbus meter");
        let plain = layout_for(&node(0x1234, 1, "Serial-DeviceNet Bridge", 18), known);
        assert_eq!((plain.profile.clone(), plain.with_status), (ImageProfile::Breaker, false));
        let status = layout_for(&node(0x1234, 1, "Serial-DeviceNet Bridge", 20), known);
        assert_eq!((status.profile, status.with_status), (ImageProfile::Breaker, true));
        let meter = &known[1].converter.device.identity;
        let m = layout_for(&node(meter.vendor_id, meter.product_code, meter.product_name.as_str(), 0), known);
        assert!(matches!(m.profile, ImageProfile::Modbus { .. }), "{m:?}");
        let other = layout_for(&node(0x0001, 1, "Serial-DeviceNet Bridge", 18), known);
        assert_eq!(other.profile, ImageProfile::Raw);
        let renamed = layout_for(&node(0x1234, 1, "Something else", 18), known);
        assert_eq!(renamed.profile, ImageProfile::Raw);
    }

    #[test]
    fn macs_are_checked() {
        assert_eq!(parse_mac("63").unwrap(), 63);
        for bad in ["64", "-1", "x", "", "999"] {
            assert_eq!(parse_mac(bad).unwrap_err().status, 400);
        }
    }
}
