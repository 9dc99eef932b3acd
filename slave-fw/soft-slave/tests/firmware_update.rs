//! The firmware update object served by the bridge (`--firmware-dir`), driven by the master
//! harness over an in-process CAN link in real time: an image signed with the TEST key is
//! announced, transferred in fragmented 128-byte chunks, verified and applied; the soft slave
//! then restarts as after an Identity Reset and reports the new revision, confirmed, and
//! `active.bin` holds the image and its trailer. The SLCAN system tests of `dnet-master
//! firmware-update` drive the same object on ptys.

mod common;

use common::{mac, ChannelBus};
use devicenet::explicit::{Request, ServiceCode};
use devicenet::Duration;
use fw_image::{sign, ImageInfo, Revision, INFO_LEN, INFO_OFFSET};
use master_core::client::Port;
use master_core::error::MasterError;
use master_core::master::{Master, MasterConfig};
use master_core::session::Session;
use slave_fw::converter::ConverterConfig;
use slave_fw::update::UPDATE_CLASS;
use soft_slave::bridge::Bridge;
use soft_slave::clock::Clock;
use soft_slave::firmware::{own_revision, FirmwareDir};
use soft_slave::serial::SerialLine;
use std::os::unix::net::UnixStream;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

const NEW: Revision = Revision { major: 9, minor: 4 };

fn keys() -> PathBuf {
    common::workspace_dir().join("contrib/keys")
}

fn call(master: &mut Master<'_, '_>, service: u8, data: &[u8]) -> Result<Vec<u8>, MasterError> {
    let req = Request { service: ServiceCode::from(service), class: UPDATE_CLASS, instance: 1, data };
    master.request_ok(mac(), Port::Explicit, &req).map(|(d, _)| d)
}

#[test]
fn an_image_is_sent_verified_applied_and_reported_after_the_restart() {
    let dir = std::env::temp_dir().join(format!("soft-slave-firmware-update-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let clock = Clock::start();
    let (mut master_end, slave_end) = ChannelBus::pair(clock);
    let (ours, _instrument) = UnixStream::pair().unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let bridge_stop = Arc::clone(&stop);
    let fw = FirmwareDir::new(&dir, &keys().join("test-ed25519.public"), 1).unwrap();
    let bridge = std::thread::spawn(move || {
        let serial = SerialLine::from_stream(ours, "socketpair", clock).unwrap();
        let mut bridge =
            Bridge::new(ConverterConfig::breaker_reference(), Box::new(slave_end), serial, clock).unwrap();
        bridge.set_firmware(fw).unwrap();
        bridge.run(&bridge_stop, None).unwrap()
    });

    // 2,000 bytes: 16 chunks, the last of 80.
    let mut image: Vec<u8> = (0..2000u32).map(|i| (i * 13) as u8).collect();
    image[INFO_OFFSET..INFO_OFFSET + INFO_LEN]
        .copy_from_slice(&ImageInfo { board_id: 1, revision: NEW }.to_bytes());
    let seed: [u8; 32] = std::fs::read(keys().join("test-ed25519.secret")).unwrap().try_into().unwrap();
    let trailer = sign(&image, &seed).unwrap();

    let mut session = Session::new(&mut master_end);
    let mut master = Master::new(&mut session, MasterConfig::default());
    master.open_explicit(mac()).unwrap();
    let own = own_revision();
    assert_eq!(call(&mut master, 0x0E, &[2]).unwrap(), [own.major, own.minor]);

    let mut update = (image.len() as u32).to_le_bytes().to_vec();
    update.extend_from_slice(&1u16.to_le_bytes());
    update.extend_from_slice(&[NEW.major, NEW.minor]);
    update.extend_from_slice(b"test-img");
    assert_eq!(call(&mut master, 0x4B, &update).unwrap(), [128, 0, 0, 0, 0, 0]);
    for (n, chunk) in image.chunks(128).enumerate() {
        let mut data = (n as u32).to_le_bytes().to_vec();
        data.extend_from_slice(chunk);
        let answer = call(&mut master, 0x4D, &data).unwrap();
        assert_eq!(answer[..4], (n as u32).to_le_bytes());
    }
    assert_eq!(call(&mut master, 0x4C, &trailer.to_bytes()).unwrap(), [3, 0]);
    assert_eq!(call(&mut master, 0x4E, &[]).unwrap(), Vec::<u8>::new());

    // The restart: the old connection is gone; the soft slave comes back on-line.
    let start = master.session.now();
    master.idle_until(start + Duration::from_millis(300)).unwrap();
    master.release_held().ok();
    let mut master = Master::new(&mut session, MasterConfig::default());
    master.open_explicit(mac()).unwrap();
    assert_eq!(call(&mut master, 0x0E, &[2]).unwrap(), [NEW.major, NEW.minor], "the new revision");
    assert_eq!(call(&mut master, 0x0E, &[1]).unwrap(), [0], "confirmed once on-line");
    let active = std::fs::read(dir.join("active.bin")).unwrap();
    assert_eq!(&active[..image.len()], &image[..]);
    assert_eq!(&active[image.len()..], &trailer.to_bytes()[..]);

    stop.store(true, Ordering::Relaxed);
    let summary = bridge.join().unwrap();
    assert_eq!(summary.resets, 1, "one restart, Apply's");
    std::fs::remove_dir_all(&dir).unwrap();
}
