//! `dnet-master ui --modbus-tcp ADDR`: the scanner's status tables and every node's I/O images
//! served read-only over Modbus TCP ([`dnet_modbus_tcp`]), beside the web console. The register
//! map is the guide's page `docs/src/plant/modbus-tcp.md`.
//!
//! Modbus TCP has no authentication: whoever reaches the port reads the plant's data. So an
//! address other than loopback is refused (exit 2, before the bus is touched) unless
//! `--modbus-tcp-public` says that is meant; and the server takes no write at all (outputs and
//! breaker commands need a user of the console).

use clap::Args;
use dnet_modbus_tcp::server::{CONNECTIONS_LIMIT, IDLE_TIMEOUT};
use dnet_modbus_tcp::{ModbusServer, ServerConfig, ServerError};
use dnet_scanner::model::Shared;
use harness_common::error::HarnessError;
use std::net::SocketAddr;
use std::sync::Arc;

/// The Modbus TCP options of `ui`.
#[derive(Args, Clone, Debug)]
pub struct ModbusArgs {
    /// Serve the scanner's status tables and the nodes' I/O images over Modbus TCP, read-only, at
    /// IP:PORT (port 0: any free port; the address is printed). Register map: the guide's Modbus
    /// TCP page.
    #[arg(long, value_name = "ADDR")]
    pub modbus_tcp: Option<String>,
    /// Allow --modbus-tcp on an address other than loopback: Modbus TCP has no authentication,
    /// whoever reaches the port reads the plant's data.
    #[arg(long, requires = "modbus_tcp")]
    pub modbus_tcp_public: bool,
    /// Modbus TCP connections served at once (1-64); one more is closed at once.
    #[arg(long, value_name = "N", default_value_t = 8, requires = "modbus_tcp",
          value_parser = clap::value_parser!(u16).range(1..=CONNECTIONS_LIMIT as i64))]
    pub modbus_tcp_connections: u16,
}

impl ModbusArgs {
    /// The address to listen on, checked: an `IP:PORT`, loopback unless `--modbus-tcp-public`.
    /// `None` without `--modbus-tcp`.
    pub fn address(&self) -> Result<Option<SocketAddr>, HarnessError> {
        let Some(text) = &self.modbus_tcp else { return Ok(None) };
        let address: SocketAddr = text.parse().map_err(|_| HarnessError::InvalidValue {
            option: "--modbus-tcp",
            value: text.clone(),
            expected: "IP:PORT (127.0.0.1:5020, [::1]:5020)",
        })?;
        if !address.ip().is_loopback() && !self.modbus_tcp_public {
            return Err(HarnessError::InvalidValue {
                option: "--modbus-tcp",
                value: text.clone(),
                expected: "a loopback address: Modbus TCP has no authentication \
                           (give --modbus-tcp-public to serve it on the network)",
            });
        }
        Ok(Some(address))
    }

    /// Starts the server on `shared` when `--modbus-tcp` is given (the address checked and bound
    /// here: a refusal is a usage error, exit 2, before the bus is touched).
    pub fn start(&self, shared: &Arc<Shared>) -> Result<Option<ModbusServer>, HarnessError> {
        let Some(address) = self.address()? else { return Ok(None) };
        let config = ServerConfig {
            max_connections: usize::from(self.modbus_tcp_connections),
            idle_timeout: IDLE_TIMEOUT,
        };
        ModbusServer::start(address, config, Arc::clone(shared)).map(Some).map_err(|e| match e {
            ServerError::Listen { address, source } => {
                HarnessError::Listen { address: address.to_string(), error: source }
            }
            other => HarnessError::ConsoleStart { address: address.to_string(), error: other.to_string() },
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    fn args(addr: &str, public: bool) -> ModbusArgs {
        ModbusArgs { modbus_tcp: Some(addr.into()), modbus_tcp_public: public, modbus_tcp_connections: 8 }
    }

    #[rstest]
    #[case::loopback_v4("127.0.0.1:5020", false, true)]
    #[case::loopback_v6("[::1]:5020", false, true)]
    #[case::any_refused("0.0.0.0:502", false, false)]
    #[case::lan_refused("192.168.1.10:502", false, false)]
    #[case::any_public("0.0.0.0:502", true, true)]
    #[case::not_an_address("localhost:502", false, false)]
    #[case::no_port("127.0.0.1", false, false)]
    fn addresses(#[case] addr: &str, #[case] public: bool, #[case] accepted: bool) {
        let result = args(addr, public).address();
        assert_eq!(result.is_ok(), accepted, "{addr}: {result:?}");
        if let Err(e) = result {
            assert_eq!(e.exit_code(), 2);
            assert!(e.to_string().contains(addr), "{e}");
        }
    }

    #[test]
    fn nothing_without_the_option() {
        let none = ModbusArgs { modbus_tcp: None, modbus_tcp_public: false, modbus_tcp_connections: 8 };
        assert!(none.address().unwrap().is_none());
    }
}
