//! The address `--opcua` names: `opc.tcp://HOST:PORT[/]` or `HOST:PORT`, resolved to one socket
//! address, and whether it is loopback (the rule `ui` applies to its console: a listener beyond
//! loopback needs accounts).

use crate::OpcUaError;
use std::net::{SocketAddr, ToSocketAddrs};

/// The TCP port OPC UA servers listen on by default (IANA "opcua-tcp", 4840).
pub const DEFAULT_PORT: u16 = 4840;

/// Where the server listens: the text given and the socket address it resolved to.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Endpoint {
    /// The host as given (`127.0.0.1`, `localhost`, `::1`), used in the endpoint URL.
    pub host: String,
    /// The socket address bound (port 0: any free port, chosen when bound).
    pub addr: SocketAddr,
}

impl Endpoint {
    /// Parses `opc.tcp://HOST[:PORT][/]` or `HOST[:PORT]` (port 4840 when none is given; an IPv6
    /// host in brackets, `[::1]:4840`). An address that does not resolve, a path after the port,
    /// or another scheme is an error naming the text.
    pub fn parse(text: &str) -> Result<Endpoint, OpcUaError> {
        let bad = |why: &str| OpcUaError::Address { address: text.to_string(), why: why.to_string() };
        let rest = match text.split_once("://") {
            Some(("opc.tcp", rest)) => rest,
            Some((scheme, _)) => return Err(bad(&format!("scheme {scheme:?}: only opc.tcp"))),
            None => text,
        };
        let rest = rest.strip_suffix('/').unwrap_or(rest);
        if rest.is_empty() {
            return Err(bad("no host"));
        }
        if rest.contains('/') {
            return Err(bad("a path after the port: the server has one endpoint, at /"));
        }
        let (host, port) = split_host_port(rest).ok_or_else(|| bad("expected HOST:PORT"))?;
        if host.is_empty() {
            return Err(bad("no host"));
        }
        let port = match port {
            Some(p) => p.parse::<u16>().map_err(|_| bad(&format!("port {p:?}: expected 0-65535")))?,
            None => DEFAULT_PORT,
        };
        let addr = (host, port)
            .to_socket_addrs()
            .map_err(|e| bad(&format!("cannot resolve {host}: {e}")))?
            .next()
            .ok_or_else(|| bad(&format!("{host} resolves to no address")))?;
        Ok(Endpoint { host: host.to_string(), addr })
    }

    /// `true` when the address is loopback (127.0.0.0/8, ::1).
    #[must_use]
    pub fn is_loopback(&self) -> bool {
        self.addr.ip().is_loopback()
    }
}

/// `host` and the port text of `HOST[:PORT]` / `[V6][:PORT]`; `None` when malformed.
fn split_host_port(text: &str) -> Option<(&str, Option<&str>)> {
    if let Some(v6) = text.strip_prefix('[') {
        let (host, after) = v6.split_once(']')?;
        return match after {
            "" => Some((host, None)),
            _ => Some((host, Some(after.strip_prefix(':')?))),
        };
    }
    match text.split_once(':') {
        Some((host, port)) if !port.contains(':') => Some((host, Some(port))),
        Some(_) => None,
        None => Some((text, None)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn url_and_bare_forms_resolve_to_the_same_address() {
        let url = Endpoint::parse("opc.tcp://127.0.0.1:4841/").unwrap();
        let bare = Endpoint::parse("127.0.0.1:4841").unwrap();
        assert_eq!(url, bare);
        assert_eq!(url.addr.port(), 4841);
        assert!(url.is_loopback());
    }

    #[test]
    fn default_port_and_ipv6() {
        assert_eq!(Endpoint::parse("127.0.0.1").unwrap().addr.port(), DEFAULT_PORT);
        let v6 = Endpoint::parse("opc.tcp://[::1]:0").unwrap();
        assert_eq!((v6.host.as_str(), v6.addr.port(), v6.is_loopback()), ("::1", 0, true));
    }

    #[test]
    fn any_address_is_not_loopback() {
        assert!(!Endpoint::parse("0.0.0.0:4840").unwrap().is_loopback());
    }

    #[test]
    fn malformed_addresses_are_refused_with_the_text() {
        for bad in ["http://127.0.0.1:4840", "opc.tcp://", "127.0.0.1:99999", "127.0.0.1:48/x", ":4840"] {
            let e = Endpoint::parse(bad).unwrap_err().to_string();
            assert!(e.contains(bad), "{bad}: {e}");
        }
    }
}
