//! # harness-common
//!
//! What the bench DeviceNet master's crates share: `dnet-master` (crate `master_harness`, the
//! command line), the plant scanner (`dnet_scanner`) and the conformance suite
//! (`dnet_conformance`) all report failures, progress and transcripts the same way through it.
//!
//! | module | what it holds |
//! |---|---|
//! | [`error`] | [`HarnessError`](error::HarnessError): every failure of a command named |
//! | [`console`] | progress lines on a terminal, the stop asked for by SIGINT / SIGTERM |
//! | [`table`] | the frame-by-frame table and the JSON form of a record |
//!
//! It holds no protocol: that is `master_core`'s. Nothing of the product depends on it.

pub mod console;
pub mod error;
pub mod table;

/// The git commit this program was built from (`-modified` when the tree had changes), or
/// `unknown commit` outside a git checkout.
pub const GIT_COMMIT: &str = git_version::git_version!(
    args = ["--always", "--dirty=-modified", "--abbrev=12"],
    fallback = "unknown commit"
);

/// The version of `dnet-master` and of its reports: the package version and the git commit,
/// `0.1.0 (1a2b3c4d5e6f)`.
#[must_use]
pub fn version() -> &'static str {
    static VERSION: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    VERSION.get_or_init(|| format!("{} ({GIT_COMMIT})", env!("CARGO_PKG_VERSION")))
}
