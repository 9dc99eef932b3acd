//! Who may drive the console: the checks every request passes before it is routed.
//!
//! A page from another site, opened in the same browser, can send requests to the console
//! (cross-site request forgery), and a name of its own that resolves to the console's address can
//! make the browser treat the console as that site (DNS rebinding). So:
//!
//! - every request names the console in `Host`: the listen address, or a loopback name or address
//!   (`localhost`, `127.0.0.1`, `[::1]`, any port: an SSH tunnel), or, when listening on every
//!   interface (`0.0.0.0`, `[::]`), any IP address with the listen port. A DNS name other than
//!   `localhost` is refused: that is what a rebinding page sends;
//! - every state-changing request (anything but `GET` and `HEAD`) also carries
//!   - `Origin` equal to the console's own origin, `http://` (`https://` with TLS) and the `Host`
//!     it was sent to;
//!   - `Content-Type: application/json`, which a cross-site form cannot send;
//!   - the caller's token in `X-CSRF-Token` (checked after this guard, in `auth`, since the token
//!     is the session's: random per login with `--users`, per process without), given by
//!     `GET /api/session` / `GET /api/token` and never readable by another site (no CORS headers
//!     are ever sent).
//!
//! Anything else is refused with `403` and the reason, before the body is read. Who the caller is
//! and what its role may do (accounts, sessions) is checked next, in `auth`.

use std::net::{IpAddr, SocketAddr};

/// The header that carries the page's token.
pub const TOKEN_HEADER: &str = "X-CSRF-Token";

/// Why a request was refused (answered `403`).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum GuardError {
    /// No `Host` header.
    #[error("no Host header: the console answers requests for its own address only")]
    NoHost,
    /// `Host` names something other than the console.
    #[error("Host {0:?} is not this console's address")]
    ForeignHost(String),
    /// A state-changing request without `Origin`.
    #[error("no Origin header: a state-changing request must come from the console's own page")]
    NoOrigin,
    /// `Origin` names another site.
    #[error("Origin {got:?} is not the console's own ({want:?})")]
    ForeignOrigin {
        /// What was sent.
        got: String,
        /// The console's origin for that request.
        want: String,
    },
    /// A content type other than `application/json`.
    #[error("Content-Type {0:?}: a state-changing request must be application/json")]
    ContentType(String),
    /// No token.
    #[error("no X-CSRF-Token header: the console's page sends its token with every change")]
    NoToken,
    /// A token that is not this process's.
    #[error("wrong X-CSRF-Token: reload the console's page")]
    WrongToken,
}

/// The console's guard: its listen address and scheme.
pub(crate) struct Guard {
    listen: SocketAddr,
    /// `http` or `https`.
    scheme: &'static str,
}

/// A fresh token: 16 random bytes from the operating system's generator (`getrandom`: the
/// `getrandom` call on Linux, `ProcessPrng` on Windows) as 32 hex digits.
pub(crate) fn new_token() -> std::io::Result<String> {
    let mut bytes = [0u8; 16];
    getrandom::fill(&mut bytes).map_err(std::io::Error::other)?;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}

/// The host part and the port of a `Host` value (`127.0.0.1:8080`, `[::1]:8080`, `localhost`).
fn split_host(host: &str) -> (&str, Option<u16>) {
    if let Some(rest) = host.strip_prefix('[') {
        if let Some((ip, after)) = rest.split_once(']') {
            return (ip, after.strip_prefix(':').and_then(|p| p.parse().ok()));
        }
    }
    match host.rsplit_once(':') {
        Some((h, p)) if !h.contains(':') => (h, p.parse().ok()),
        _ => (host, None),
    }
}

impl Guard {
    /// The guard of a console listening on `listen`, over TLS when `tls`.
    pub(crate) fn new(listen: SocketAddr, tls: bool) -> Guard {
        Guard { listen, scheme: if tls { "https" } else { "http" } }
    }

    /// Whether `host` (a `Host` header's value) names this console.
    fn own_host(&self, host: &str) -> bool {
        let (name, port) = split_host(host);
        let port = port.unwrap_or(80);
        if name.eq_ignore_ascii_case("localhost") {
            return true;
        }
        let Ok(ip) = name.parse::<IpAddr>() else { return false };
        ip.is_loopback()
            || (port == self.listen.port() && (ip == self.listen.ip() || self.listen.ip().is_unspecified()))
    }

    /// Checks a request: `method` and its headers as (name, value) pairs.
    pub(crate) fn check<'a>(
        &self,
        method: &str,
        headers: impl Iterator<Item = (&'a str, &'a str)> + Clone,
    ) -> Result<(), GuardError> {
        let find =
            |name: &str| headers.clone().find(|(k, _)| k.eq_ignore_ascii_case(name)).map(|(_, v)| v.trim());
        let host = find("Host").filter(|h| !h.is_empty()).ok_or(GuardError::NoHost)?;
        if !self.own_host(host) {
            return Err(GuardError::ForeignHost(host.to_string()));
        }
        if method.eq_ignore_ascii_case("GET") || method.eq_ignore_ascii_case("HEAD") {
            return Ok(());
        }
        let want = format!("{}://{host}", self.scheme);
        match find("Origin") {
            None => return Err(GuardError::NoOrigin),
            Some(o) if !o.eq_ignore_ascii_case(&want) => {
                return Err(GuardError::ForeignOrigin { got: o.to_string(), want })
            }
            Some(_) => {}
        }
        let content_type = find("Content-Type").unwrap_or("");
        let media = content_type.split(';').next().unwrap_or("").trim();
        if !media.eq_ignore_ascii_case("application/json") {
            return Err(GuardError::ContentType(content_type.to_string()));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    const TOKEN: &str = "00112233445566778899aabbccddeeff";

    fn guard(listen: &str) -> Guard {
        Guard::new(listen.parse().unwrap(), false)
    }

    fn good(host: &str) -> Vec<(String, String)> {
        vec![
            ("Host".into(), host.into()),
            ("Origin".into(), format!("http://{host}")),
            ("Content-Type".into(), "application/json".into()),
            ("X-CSRF-Token".into(), TOKEN.into()),
        ]
    }

    fn check(g: &Guard, method: &str, headers: &[(String, String)]) -> Result<(), GuardError> {
        g.check(method, headers.iter().map(|(k, v)| (k.as_str(), v.as_str())))
    }

    fn without(mut h: Vec<(String, String)>, name: &str) -> Vec<(String, String)> {
        h.retain(|(k, _)| k != name);
        h
    }

    fn with(mut h: Vec<(String, String)>, name: &str, value: &str) -> Vec<(String, String)> {
        h.retain(|(k, _)| k != name);
        h.push((name.into(), value.into()));
        h
    }

    #[rstest]
    #[case::listen_address("127.0.0.1:8080", "127.0.0.1:8080")]
    #[case::localhost("127.0.0.1:8080", "localhost:8080")]
    #[case::tunnel_port("127.0.0.1:8080", "localhost:9000")]
    #[case::ipv6_loopback("127.0.0.1:8080", "[::1]:8080")]
    #[case::every_interface("0.0.0.0:8080", "192.168.1.20:8080")]
    #[case::lan_address("192.168.1.20:8080", "192.168.1.20:8080")]
    fn the_console_s_own_requests_pass(#[case] listen: &str, #[case] host: &str) {
        assert_eq!(check(&guard(listen), "POST", &good(host)), Ok(()));
    }

    #[rstest]
    #[case::rebinding_name("127.0.0.1:8080", "evil.example:8080")]
    #[case::other_address("192.168.1.20:8080", "192.168.1.21:8080")]
    #[case::other_port("0.0.0.0:8080", "192.168.1.20:9090")]
    fn a_foreign_host_is_refused_even_for_get(#[case] listen: &str, #[case] host: &str) {
        let e = check(&guard(listen), "GET", &good(host)).unwrap_err();
        assert_eq!(e, GuardError::ForeignHost(host.into()));
    }

    #[test]
    fn each_missing_or_wrong_header_is_refused_by_name() {
        let g = guard("127.0.0.1:8080");
        let h = good("127.0.0.1:8080");
        assert_eq!(check(&g, "POST", &without(h.clone(), "Host")), Err(GuardError::NoHost));
        assert_eq!(check(&g, "POST", &without(h.clone(), "Origin")), Err(GuardError::NoOrigin));
        assert!(matches!(
            check(&g, "POST", &with(h.clone(), "Origin", "http://evil.example")),
            Err(GuardError::ForeignOrigin { .. })
        ));
        assert!(matches!(
            check(&g, "DELETE", &with(h.clone(), "Content-Type", "text/plain")),
            Err(GuardError::ContentType(_))
        ));
        // Over TLS the origin is https.
        assert!(matches!(
            check(&Guard::new("127.0.0.1:8080".parse().unwrap(), true), "POST", &h),
            Err(GuardError::ForeignOrigin { .. })
        ));
        assert_eq!(
            check(&g, "POST", &with(h.clone(), "Content-Type", "application/json; charset=utf-8")),
            Ok(())
        );
        // Reading needs no token.
        assert_eq!(check(&g, "GET", &[("Host".into(), "127.0.0.1:8080".into())]), Ok(()));
    }

    #[test]
    fn tokens_are_random_hex() {
        let (a, b) = (new_token().unwrap(), new_token().unwrap());
        assert_eq!(a.len(), 32);
        assert!(a.bytes().all(|c| c.is_ascii_hexdigit()));
        assert_ne!(a, b);
    }
}
