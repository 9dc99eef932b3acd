//! `dnet-master scanner`: keeps every node of a scan list in I/O, as a DeviceNet scanner does.
//! (The engine is being written; [`model`] holds what it shares with the console.)

pub mod model;
