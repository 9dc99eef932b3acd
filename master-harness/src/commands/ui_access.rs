//! `dnet-master ui --users FILE --tls-cert FILE --tls-key FILE`: who may use the console and how
//! it is reached ([`dnet_scanner::ui::Access`]), checked before the bus is touched.
//!
//! Without `--users` the console has no logins, so it listens on loopback only: `--listen` on any
//! other address (`0.0.0.0`, a LAN address) is refused (exit 2) — anyone who reached the port
//! could otherwise switch plant equipment. A users file that does not load, a certificate or key
//! that does not load, or one of `--tls-cert` / `--tls-key` without the other is refused the same
//! way, naming the file.

use clap::Args;
use dnet_scanner::accounts::Users;
use dnet_scanner::ui::{tls, Access};
use harness_common::error::HarnessError;
use std::net::{SocketAddr, ToSocketAddrs};
use std::path::PathBuf;

/// The console's accounts and TLS.
#[derive(Args, Clone, Debug, Default)]
pub struct AccessArgs {
    /// Logins on: the users file (`dnet-master user add FILE NAME --role ROLE`). Required to
    /// listen on an address other than loopback.
    #[arg(long, value_name = "FILE")]
    pub users: Option<PathBuf>,
    /// Serve over TLS with this certificate chain (PEM); needs --tls-key.
    #[arg(long, value_name = "FILE.pem", requires = "tls_key")]
    pub tls_cert: Option<PathBuf>,
    /// The TLS private key (PEM: PKCS#8, PKCS#1 or SEC1); needs --tls-cert.
    #[arg(long, value_name = "FILE.pem", requires = "tls_cert")]
    pub tls_key: Option<PathBuf>,
}

/// Whether every address `listen` names is a loopback address.
fn loopback_only(listen: &str) -> bool {
    let addrs: Vec<SocketAddr> = match listen.parse::<SocketAddr>() {
        Ok(a) => vec![a],
        Err(_) => listen.to_socket_addrs().map(Iterator::collect).unwrap_or_default(),
    };
    !addrs.is_empty() && addrs.iter().all(|a| a.ip().is_loopback())
}

impl AccessArgs {
    /// A warning for a console on `listen` beyond loopback without TLS: passwords and session
    /// cookies would cross the network readable.
    #[must_use]
    pub fn warning(&self, listen: &str) -> Option<&'static str> {
        (self.tls_cert.is_none() && !loopback_only(listen)).then_some(
            "the console listens beyond loopback without TLS: passwords and session cookies cross the \
             network readable (give --tls-cert and --tls-key)",
        )
    }

    /// The accounts and TLS configuration for a console on `listen`, or the refusal.
    pub fn open(&self, listen: &str) -> Result<Access, HarnessError> {
        let start = |error: String| HarnessError::ConsoleStart { address: listen.to_string(), error };
        if self.users.is_none() && !loopback_only(listen) {
            return Err(HarnessError::InvalidValue {
                option: "--listen",
                value: listen.to_string(),
                expected: "a loopback address (127.0.0.1, [::1], localhost) unless --users FILE turns \
                           logins on: without accounts anyone who reaches the port could command the plant",
            });
        }
        let users = match &self.users {
            Some(path) => Some(Users::load(path).map_err(|e| start(e.to_string()))?),
            None => None,
        };
        let tls = match (&self.tls_cert, &self.tls_key) {
            (Some(cert), Some(key)) => Some(tls::server_config(cert, key).map_err(|e| start(e.to_string()))?),
            _ => None,
        };
        Ok(Access { users, tls, project: None })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    #[rstest]
    #[case::v4("127.0.0.1:8080", true)]
    #[case::v6("[::1]:0", true)]
    #[case::name("localhost:0", true)]
    #[case::every_interface("0.0.0.0:8080", false)]
    #[case::every_interface_v6("[::]:8080", false)]
    #[case::lan("192.168.1.20:8080", false)]
    #[case::garbage("nonsense", false)]
    fn only_loopback_without_users(#[case] listen: &str, #[case] ok: bool) {
        assert_eq!(loopback_only(listen), ok);
        let r = AccessArgs::default().open(listen);
        assert_eq!(r.is_ok(), ok, "{listen}");
        if let Err(e) = r {
            assert_eq!(e.exit_code(), 2);
            assert!(e.to_string().contains("--users"), "{e}");
        }
        assert_eq!(AccessArgs::default().warning(listen).is_some(), !ok);
    }
}
