//! The console's HTTP/1.1 server: one accepting thread and a fixed pool of [`WORKERS`] threads.
//!
//! Each connection carries one request and is closed after the answer (`Connection: close`): the
//! page polls a handful of small JSON documents, so keeping connections open buys nothing and
//! would tie a worker to an idle client. A new connection waits in the accepting thread, without a
//! thread of its own, until it sends something (at most [`MAX_IDLE`] such, each for at most
//! [`IDLE_TIMEOUT`]; browsers open spare connections they may never use); then it waits in a queue
//! of [`QUEUE`] for a free worker. Beyond either bound a connection is answered `503` at once and
//! closed. A client that stops sending mid-request holds a worker for at most [`IDLE_TIMEOUT`].
//! So however many clients connect, the console keeps `WORKERS + 1` threads and bounded queues
//! (5,000 idle connections: the same threads, and `503` for those beyond the bounds).
//!
//! `tiny_http`, used before, gives every connection a thread of its own and has no setting to
//! bound them; this server replaces it with the part the console needs: a request line, headers
//! (at most [`MAX_HEAD`] bytes), a body announced by `Content-Length` (at most
//! [`super::MAX_BODY`], larger bodies refused unread with `413`). Nothing a client sends can panic
//! it.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Worker threads answering requests.
pub const WORKERS: usize = 16;
/// Connections that sent a request, waiting for a worker; beyond them `503`.
pub const QUEUE: usize = 64;
/// Connections that sent nothing yet, held without a thread; beyond them `503`.
pub const MAX_IDLE: usize = 256;
/// How long a connection may stay silent (or a write blocked) before it is closed.
pub const IDLE_TIMEOUT: Duration = Duration::from_secs(10);
/// The largest request line and headers, bytes.
pub const MAX_HEAD: usize = 16 * 1024;

/// A request, read whole.
#[derive(Debug, Clone)]
pub(crate) struct Request {
    /// `GET`, `POST`, ...
    pub(crate) method: String,
    /// The path and query as sent.
    pub(crate) url: String,
    /// The headers in order, names as sent.
    pub(crate) headers: Vec<(String, String)>,
    /// The body (empty when none).
    pub(crate) body: Vec<u8>,
}

impl Request {
    /// The headers as (name, value) pairs.
    pub(crate) fn header_pairs(&self) -> impl Iterator<Item = (&str, &str)> + Clone {
        self.headers.iter().map(|(k, v)| (k.as_str(), v.as_str()))
    }
}

/// A response: status, headers and the whole body.
#[derive(Debug, Clone)]
pub(crate) struct Response {
    pub(crate) status: u16,
    headers: Vec<(String, String)>,
    pub(crate) body: Vec<u8>,
}

impl Response {
    /// A response with `status`, a `Content-Type` and `body`; never cached.
    pub(crate) fn new(status: u16, content_type: &str, body: Vec<u8>) -> Response {
        let headers = vec![
            ("Content-Type".to_string(), content_type.to_string()),
            ("Cache-Control".to_string(), "no-store".to_string()),
        ];
        Response { status, headers, body }
    }

    /// Adds a header.
    pub(crate) fn add_header(&mut self, name: &str, value: &str) {
        self.headers.push((name.to_string(), value.to_string()));
    }

    /// Writes the response (`head_only`: for `HEAD`, without the body).
    fn write_to(&self, w: &mut dyn Write, head_only: bool) -> std::io::Result<()> {
        let mut head = format!("HTTP/1.1 {} {}\r\n", self.status, reason(self.status));
        for (k, v) in &self.headers {
            head.push_str(&format!("{k}: {v}\r\n"));
        }
        head.push_str(&format!("Content-Length: {}\r\nConnection: close\r\n\r\n", self.body.len()));
        w.write_all(head.as_bytes())?;
        if !head_only {
            w.write_all(&self.body)?;
        }
        w.flush()
    }
}

fn reason(status: u16) -> &'static str {
    match status {
        200 => "OK",
        204 => "No Content",
        400 => "Bad Request",
        401 => "Unauthorized",
        403 => "Forbidden",
        404 => "Not Found",
        405 => "Method Not Allowed",
        409 => "Conflict",
        411 => "Length Required",
        413 => "Payload Too Large",
        431 => "Request Header Fields Too Large",
        500 => "Internal Server Error",
        503 => "Service Unavailable",
        504 => "Gateway Timeout",
        _ => "",
    }
}

/// Why no request could be read from a connection.
#[derive(Debug)]
pub(crate) enum ReadError {
    /// The client closed, went silent or the connection failed: nothing to answer.
    Gone,
    /// A malformed or refused request: answered with this status and reason.
    Refused(u16, String),
}

/// One line of the head, without its CRLF; `budget` bytes of head remain.
fn head_line(r: &mut dyn BufRead, budget: &mut usize) -> Result<String, ReadError> {
    let mut line = Vec::new();
    let n = r.take(*budget as u64 + 1).read_until(b'\n', &mut line).map_err(|_| ReadError::Gone)?;
    if n == 0 {
        return Err(ReadError::Gone);
    }
    if n > *budget {
        return Err(ReadError::Refused(431, format!("request head over {MAX_HEAD} bytes")));
    }
    *budget -= n;
    if line.last() != Some(&b'\n') {
        return Err(ReadError::Gone);
    }
    while matches!(line.last(), Some(b'\n' | b'\r')) {
        line.pop();
    }
    String::from_utf8(line).map_err(|_| ReadError::Refused(400, "request head is not UTF-8".into()))
}

/// Reads one request: the head, then a body of at most `max_body` bytes.
pub(crate) fn read_request(r: &mut dyn BufRead, max_body: usize) -> Result<Request, ReadError> {
    let mut budget = MAX_HEAD;
    let line = head_line(r, &mut budget)?;
    let mut parts = line.split(' ');
    let (Some(method), Some(url), Some(version), None) =
        (parts.next(), parts.next(), parts.next(), parts.next())
    else {
        return Err(ReadError::Refused(400, format!("bad request line {line:?}")));
    };
    if !version.starts_with("HTTP/1.") || method.is_empty() || !url.starts_with('/') {
        return Err(ReadError::Refused(400, format!("bad request line {line:?}")));
    }
    let mut headers = Vec::new();
    loop {
        let h = head_line(r, &mut budget)?;
        if h.is_empty() {
            break;
        }
        let Some((k, v)) = h.split_once(':') else {
            return Err(ReadError::Refused(400, format!("bad header line {h:?}")));
        };
        headers.push((k.trim().to_string(), v.trim().to_string()));
    }
    let find =
        |name: &str| headers.iter().find(|(k, _)| k.eq_ignore_ascii_case(name)).map(|(_, v)| v.as_str());
    if find("Transfer-Encoding").is_some() {
        return Err(ReadError::Refused(
            411,
            "a request body needs a Content-Length (no chunked bodies)".into(),
        ));
    }
    let length = match find("Content-Length") {
        None => 0,
        Some(v) => {
            v.parse::<usize>().map_err(|_| ReadError::Refused(400, format!("bad Content-Length {v:?}")))?
        }
    };
    if length > max_body {
        return Err(ReadError::Refused(413, format!("request body of {length} bytes: at most {max_body}")));
    }
    let mut body = vec![0; length];
    r.read_exact(&mut body).map_err(|_| ReadError::Gone)?;
    Ok(Request { method: method.to_string(), url: url.to_string(), headers, body })
}

/// What answers a request.
pub(crate) type Handler = dyn Fn(&Request) -> Response + Send + Sync;
/// What answers a request that could not be read.
pub(crate) type Refusal = fn(u16, &str) -> Response;

/// A running server: [`Server::stop`] stops accepting and lets the workers end.
pub(crate) struct Server {
    stop: Arc<AtomicBool>,
    acceptor: Option<JoinHandle<()>>,
}

impl Server {
    /// Serves `listener` with `handler` on [`WORKERS`] threads.
    pub(crate) fn start(
        listener: TcpListener,
        handler: Arc<Handler>,
        refusal: Refusal,
        max_body: usize,
        tls: Option<Arc<rustls::ServerConfig>>,
    ) -> std::io::Result<Server> {
        listener.set_nonblocking(true)?;
        let (queue, waiting) = sync_channel::<TcpStream>(QUEUE);
        let waiting = Arc::new(Mutex::new(waiting));
        for i in 0..WORKERS {
            let waiting = Arc::clone(&waiting);
            let handler = Arc::clone(&handler);
            let tls = tls.clone();
            std::thread::Builder::new()
                .name(format!("ui-worker-{i}"))
                .spawn(move || work(&waiting, handler.as_ref(), refusal, max_body, tls.as_ref()))?;
        }
        let stop = Arc::new(AtomicBool::new(false));
        let acceptor = {
            let stop = Arc::clone(&stop);
            std::thread::Builder::new()
                .name("ui-accept".into())
                .spawn(move || accept(&listener, &queue, refusal, &stop))?
        };
        Ok(Server { stop, acceptor: Some(acceptor) })
    }

    /// Stops accepting (the port is released); the workers answer what they hold, then end.
    pub(crate) fn stop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(a) = self.acceptor.take() {
            let _ = a.join();
        }
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        self.stop();
    }
}

/// Whether a connection has sent something: `Some(true)` bytes wait, `Some(false)` it is closed
/// or failed, `None` nothing yet (the stream is non-blocking).
fn readable(s: &TcpStream) -> Option<bool> {
    match s.peek(&mut [0u8; 1]) {
        Ok(0) => Some(false),
        Ok(_) => Some(true),
        Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => None,
        Err(_) => Some(false),
    }
}

/// Accepts until `stop`. A new connection waits here, without a thread, until it sends something
/// (a browser opens spare connections it may never use) or [`IDLE_TIMEOUT`] ends it; at most
/// [`MAX_IDLE`] wait so, more are answered `503`. One that sent something goes to the queue, or
/// is answered `503` when the queue is full.
fn accept(listener: &TcpListener, queue: &SyncSender<TcpStream>, refusal: Refusal, stop: &AtomicBool) {
    let mut idle: Vec<(TcpStream, Instant)> = Vec::new();
    while !stop.load(Ordering::SeqCst) {
        let mut busy_now = false;
        loop {
            match listener.accept() {
                Ok((s, _)) => {
                    busy_now = true;
                    if idle.len() >= MAX_IDLE || s.set_nonblocking(true).is_err() {
                        busy(s, refusal);
                    } else {
                        idle.push((s, Instant::now()));
                    }
                }
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => break,
                // Out of file descriptors and the like: wait, the clients go away.
                Err(_) => {
                    std::thread::sleep(Duration::from_millis(50));
                    break;
                }
            }
        }
        let mut i = 0;
        while i < idle.len() {
            match readable(&idle[i].0) {
                None if idle[i].1.elapsed() < IDLE_TIMEOUT => i += 1,
                // Silent too long, closed or failed: dropped.
                None | Some(false) => drop(idle.swap_remove(i)),
                Some(true) => {
                    busy_now = true;
                    let (s, _) = idle.swap_remove(i);
                    let ready = s.set_nonblocking(false).is_ok()
                        && s.set_read_timeout(Some(IDLE_TIMEOUT)).is_ok()
                        && s.set_write_timeout(Some(IDLE_TIMEOUT)).is_ok();
                    if !ready {
                        continue;
                    }
                    match queue.try_send(s) {
                        Ok(()) => {}
                        Err(TrySendError::Full(s)) => busy(s, refusal),
                        Err(TrySendError::Disconnected(_)) => return,
                    }
                }
            }
        }
        if !busy_now {
            std::thread::sleep(Duration::from_millis(2));
        }
    }
}

/// Answers `503` without a worker: what the client sent already is read first (closing with
/// unread data would reset the connection before the answer arrives).
fn busy(mut s: TcpStream, refusal: Refusal) {
    let _ = s.set_nonblocking(true);
    let mut sink = [0u8; 4096];
    while matches!(s.read(&mut sink), Ok(n) if n > 0) {}
    let _ = s.set_nonblocking(false);
    let _ = s.set_write_timeout(Some(Duration::from_millis(200)));
    let r = refusal(
        503,
        &format!("the console is busy ({WORKERS} requests, {QUEUE} waiting, {MAX_IDLE} idle connections): try again"),
    );
    let _ = r.write_to(&mut s, false);
    let _ = s.shutdown(std::net::Shutdown::Write);
}

/// A worker: takes connections from the queue until the server is gone.
fn work(
    waiting: &Mutex<Receiver<TcpStream>>,
    handler: &Handler,
    refusal: Refusal,
    max_body: usize,
    tls: Option<&Arc<rustls::ServerConfig>>,
) {
    loop {
        let next = match waiting.lock() {
            Ok(rx) => rx.recv_timeout(Duration::from_millis(200)),
            Err(_) => return,
        };
        match next {
            Ok(stream) => match tls {
                None => answer(stream, handler, refusal, max_body),
                Some(config) => answer_tls(stream, config, handler, refusal, max_body),
            },
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => continue,
            Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => return,
        }
    }
}

/// Reads one request from `stream`, answers it and closes.
fn answer(stream: TcpStream, handler: &Handler, refusal: Refusal, max_body: usize) {
    let Ok(write_half) = stream.try_clone() else { return };
    let mut reader = BufReader::new(stream);
    let (response, head_only) = match read_request(&mut reader, max_body) {
        Ok(request) => (handler(&request), request.method == "HEAD"),
        Err(ReadError::Refused(status, why)) => (refusal(status, &why), false),
        Err(ReadError::Gone) => return,
    };
    let mut w = std::io::BufWriter::new(&write_half);
    let _ = response.write_to(&mut w, head_only);
    drop(w);
    let _ = write_half.shutdown(std::net::Shutdown::Write);
    // What the client still sends (a body refused unread) is read briefly, so that closing does
    // not reset the connection before the answer is read.
    let _ = write_half.set_read_timeout(Some(Duration::from_millis(100)));
    let mut sink = [0u8; 4096];
    let mut left = 64;
    while left > 0 && matches!(reader.get_mut().read(&mut sink), Ok(n) if n > 0) {
        left -= 1;
    }
}

/// [`answer`] over TLS: the handshake happens as the request is read (a client that fails it is
/// gone, nothing answered); the answer ends with TLS's close_notify.
fn answer_tls(
    stream: TcpStream,
    config: &Arc<rustls::ServerConfig>,
    handler: &Handler,
    refusal: Refusal,
    max_body: usize,
) {
    let Ok(conn) = rustls::ServerConnection::new(Arc::clone(config)) else { return };
    let mut tls = rustls::StreamOwned::new(conn, stream);
    let (response, head_only) = {
        let mut reader = BufReader::new(&mut tls);
        match read_request(&mut reader, max_body) {
            Ok(request) => (handler(&request), request.method == "HEAD"),
            Err(ReadError::Refused(status, why)) => (refusal(status, &why), false),
            Err(ReadError::Gone) => return,
        }
    };
    let _ = response.write_to(&mut tls, head_only);
    tls.conn.send_close_notify();
    let _ = tls.flush();
    let _ = tls.sock.shutdown(std::net::Shutdown::Write);
    // As `answer`: what the client still sends is read briefly before closing.
    let _ = tls.sock.set_read_timeout(Some(Duration::from_millis(100)));
    let mut sink = [0u8; 4096];
    let mut left = 64;
    while left > 0 && matches!(tls.sock.read(&mut sink), Ok(n) if n > 0) {
        left -= 1;
    }
}

/// The address a listener is bound to.
pub(crate) fn bind(listen: &str) -> std::io::Result<(TcpListener, SocketAddr)> {
    let l = TcpListener::bind(listen)?;
    let a = l.local_addr()?;
    Ok((l, a))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    fn read(raw: &str) -> Result<Request, ReadError> {
        read_request(&mut std::io::Cursor::new(raw.as_bytes().to_vec()), 1024)
    }

    #[test]
    fn a_request_is_read_whole() {
        let r = read("POST /api/x?a=1 HTTP/1.1\r\nHost: h\r\nContent-Length: 3\r\n\r\nabcextra").unwrap();
        assert_eq!(
            (r.method.as_str(), r.url.as_str(), r.body.as_slice()),
            ("POST", "/api/x?a=1", &b"abc"[..])
        );
        assert_eq!(r.headers, vec![("Host".into(), "h".into()), ("Content-Length".into(), "3".into())]);
    }

    #[rstest]
    #[case::bad_line("GARBAGE\r\n\r\n", 400)]
    #[case::bad_header("GET / HTTP/1.1\r\nnocolon\r\n\r\n", 400)]
    #[case::too_big("POST / HTTP/1.1\r\nContent-Length: 5000\r\n\r\n", 413)]
    #[case::chunked("POST / HTTP/1.1\r\nTransfer-Encoding: chunked\r\n\r\n", 411)]
    #[case::bad_length("POST / HTTP/1.1\r\nContent-Length: x\r\n\r\n", 400)]
    fn bad_requests_are_refused_with_a_status(#[case] raw: &str, #[case] status: u16) {
        match read(raw) {
            Err(ReadError::Refused(s, _)) => assert_eq!(s, status),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn a_huge_head_is_refused_and_a_cut_one_is_gone() {
        let huge = format!("GET / HTTP/1.1\r\nX: {}\r\n\r\n", "a".repeat(MAX_HEAD));
        assert!(matches!(read(&huge), Err(ReadError::Refused(431, _))));
        assert!(matches!(read("GET /api/sta"), Err(ReadError::Gone)));
        assert!(matches!(read("POST / HTTP/1.1\r\nContent-Length: 9\r\n\r\n02"), Err(ReadError::Gone)));
    }
}
