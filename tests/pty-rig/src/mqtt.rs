//! A mosquitto broker of the test's own, for the tests of the MQTT and Sparkplug B publishers
//! against independent clients.
//!
//! A missing mosquitto is a failure, not a skip: these tests are run on purpose (`-- --ignored`).

use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// A mosquitto of its own on a loopback port, killed when dropped.
#[derive(Debug)]
pub struct Mosquitto {
    child: Child,
    conf: PathBuf,
    port: u16,
}

impl Mosquitto {
    /// Writes `dir/mosquitto-PORT.conf` (anonymous, no persistence; with `tls` = (CA, server
    /// certificate, server key) a TLS listener) and starts mosquitto with it.
    pub fn start(dir: &Path, port: u16, tls: Option<(&Path, &Path, &Path)>) -> Mosquitto {
        let conf = dir.join(format!("mosquitto-{port}.conf"));
        let mut text = format!("listener {port} 127.0.0.1\nallow_anonymous true\npersistence false\n");
        if let Some((ca, cert, key)) = tls {
            text +=
                &format!("cafile {}\ncertfile {}\nkeyfile {}\n", ca.display(), cert.display(), key.display());
        }
        std::fs::write(&conf, text).unwrap_or_else(|e| panic!("{}: {e}", conf.display()));
        Mosquitto::run(conf, port)
    }

    /// Starts mosquitto (on `PATH`, else `/usr/sbin/mosquitto`) with `conf` and waits (10 s at most) until it listens on `port`.
    fn run(conf: PathBuf, port: u16) -> Mosquitto {
        let spawn = |program: &str| {
            Command::new(program).arg("-c").arg(&conf).stdout(Stdio::null()).stderr(Stdio::null()).spawn()
        };
        let child = spawn("mosquitto")
            .or_else(|_| spawn("/usr/sbin/mosquitto"))
            .unwrap_or_else(|e| panic!("cannot start mosquitto ({e}): apt-get install mosquitto"));
        let until = Instant::now() + Duration::from_secs(10);
        while TcpStream::connect(("127.0.0.1", port)).is_err() {
            assert!(Instant::now() < until, "mosquitto did not listen on {port}");
            std::thread::sleep(Duration::from_millis(50));
        }
        Mosquitto { child, conf, port }
    }

    /// Stops it (SIGKILL: the clients' links break as in a crash), runs `meanwhile`, and starts
    /// it again after `away`, on the same port.
    pub fn restart_after(&mut self, away: Duration, meanwhile: impl FnOnce()) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        meanwhile();
        std::thread::sleep(away);
        let again = Mosquitto::run(self.conf.clone(), self.port);
        drop(std::mem::replace(self, again));
    }
}

impl Drop for Mosquitto {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
