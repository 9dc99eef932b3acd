//! The commands of `dnet-master`, one module each ([`crate::cli`] parses and dispatches).

pub mod scanner;
pub mod ui;
